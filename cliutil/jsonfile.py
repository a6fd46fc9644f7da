"""Reading JSON that a user handed in: deep nesting is an error naming the file, never a ``RecursionError``.

Python's ``json`` parser recurses once per nesting level, so ``[[[[...]]]]`` a few thousand levels deep raises
``RecursionError`` (which no reader expects) instead of ``json.JSONDecodeError``. :func:`loads_json` turns it into
a ``json.JSONDecodeError``, so every reader's existing handling of malformed JSON applies; :func:`read_json` reads a
file and reports any malformed JSON as :class:`~cliutil.errors.BadInput` naming the file and line;
:func:`is_finite_number` tells a JSON value that is a number from text, a boolean or NaN.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from cliutil.errors import BadInput


def loads_json(text: str | bytes):
    """``json.loads(text)``; input nested too deeply for Python's parser raises ``json.JSONDecodeError`` too."""
    try:
        return json.loads(text)
    except RecursionError:
        document = text.decode("utf-8", errors="replace") if isinstance(text, bytes) else text
        raise json.JSONDecodeError(f"nested deeper than the {sys.getrecursionlimit()} levels Python's JSON parser "
                                   "can read", document, 0) from None


def read_json(path: Path):
    """The JSON document in the UTF-8 file ``path``; :class:`BadInput` naming the file (and line) if it is not one."""
    try:
        return loads_json(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError as error:
        raise BadInput(f"{path}: not UTF-8 text (byte {error.start}: {error.reason})") from None
    except json.JSONDecodeError as error:
        raise BadInput(f"{path}: invalid JSON at line {error.lineno}: {error.msg}") from None


def is_finite_number(value) -> bool:
    """Whether a parsed JSON value is a finite number: not a string (``"1.5"``), a boolean (Python's ``True`` is an
    int), NaN or an infinity (which Python's parser accepts)."""
    return type(value) in (int, float) and math.isfinite(value)
