"""Set ``drone-dji:`` fields in an existing XMP packet and keep every other byte of it (``geotag --write-exif``).

DJI writes its fields as attributes of one ``rdf:Description`` that declares the ``drone-dji`` namespace
(``drone-dji:AbsoluteAltitude="+198.31"``; element form ``<drone-dji:X>v</drone-dji:X>`` is legal XMP too). A
field already there gets the new value in place, in whichever form it has; a missing one becomes a new attribute of
that description (or of a new description, when the packet has none for the namespace). The namespace's own
prefix is used, whatever it is. The packet keeps its size where its trailing padding allows (XMP's rule for
in-place updates), and the result is parsed again (defusedxml) before it is returned.
"""

from __future__ import annotations

import re
from xml.sax.saxutils import escape

from .logs.photos import DRONE_DJI_NS, dji_xmp_text

ATTRIBUTE = r"""\s+([^\s=/>]+)\s*=\s*(?:"[^"]*"|'[^']*')"""
DESCRIPTION_START = re.compile(rf"<rdf:Description\b(?:{ATTRIBUTE})*\s*/?>")
NAMESPACE = re.compile(rf"""\bxmlns:([^\s=/>]+)\s*=\s*(["']){re.escape(DRONE_DJI_NS)}\2""")
PADDING = re.compile(r"\s*(?=<\?xpacket end=)")
#: Other names DJI firmware writes for a field (its misspelt ``GpsLongtitude``): set too where present.
ALIASES = {"GpsLongitude": ("GpsLongtitude",)}


def quoted(value: str) -> str:
    """``value`` as the text of a double-quoted attribute or an element."""
    return escape(value, {'"': "&quot;", "\n": "&#10;", "\r": "&#13;", "\t": "&#9;"})


def dji_description(text: str) -> tuple[str, re.Match] | None:
    """(prefix, start tag match) of the first ``rdf:Description`` that declares the drone-dji namespace."""
    for start in DESCRIPTION_START.finditer(text):
        if namespace := NAMESPACE.search(start.group(0)):
            return namespace.group(1), start
    return None


def set_field(text: str, prefix: str, name: str, value: str) -> str | None:
    """``text`` with ``prefix:name`` set to ``value`` where it is an attribute or element; None if it is neither."""
    qualified = re.escape(f"{prefix}:{name}")
    attribute = re.compile(rf"""(\s{qualified}\s*=\s*)(?:"[^"]*"|'[^']*')""")
    element = re.compile(rf"(<{qualified}>)[^<]*(</{qualified}>)")
    text, count = attribute.subn(lambda m: f'{m.group(1)}"{quoted(value)}"', text, count=1)
    if not count:
        text, count = element.subn(lambda m: f"{m.group(1)}{quoted(value)}{m.group(2)}", text, count=1)
    return text if count else None


def with_dji_fields(packet: bytes, values: dict[str, str]) -> bytes:
    """``packet`` with each ``drone-dji:`` field of ``values`` (name -> text) set; everything else kept.
    ValueError for a packet that is not UTF-8 XMP with an ``rdf:RDF``, or whose edit would not parse."""
    try:
        text = packet.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError("the XMP packet is not UTF-8") from None
    size = len(text.encode("utf-8"))
    found = dji_description(text)
    if found is None:
        if "</rdf:RDF>" not in text:
            raise ValueError("the XMP packet has no rdf:RDF to add the drone-dji fields to")
        text = text.replace("</rdf:RDF>", f'<rdf:Description rdf:about="" xmlns:drone-dji="{DRONE_DJI_NS}"/>\n'
                                          "</rdf:RDF>", 1)
        found = dji_description(text)
    prefix = found[0]
    added = []
    for name, value in values.items():
        present = False
        for alias in (name, *ALIASES.get(name, ())):
            changed = set_field(text, prefix, alias, value)
            if changed is not None:
                text, present = changed, True
        if not present:
            added.append(f' {prefix}:{name}="{quoted(value)}"')
    if added:
        start = dji_description(text)[1]
        close = start.end() - (2 if start.group(0).endswith("/>") else 1)
        text = text[:close] + "".join(added) + text[close:]
    text = drop_padding(text, len(text.encode("utf-8")) - size)
    dji_xmp_text(text)  # raises ValueError if the edit broke the XML
    return text.encode("utf-8")


def drop_padding(text: str, grown: int) -> str:
    """``text`` with up to ``grown`` characters of the whitespace before ``<?xpacket end=`` removed (a line break
    is kept), so that an edited packet keeps its size where its padding allows."""
    padding = PADDING.search(text)
    if grown <= 0 or padding is None:
        return text
    keep = max(1, len(padding.group(0)) - grown)
    return text[:padding.start()] + padding.group(0)[-keep:] + text[padding.end():]
