"""``geotag --write-exif`` copies (:func:`capture.geotag_io.write_exif_copy`) of real DJI photos (read-only; copies
in tmp_path): the compressed image is the original bytes, every EXIF tag (the maker note too), every XMP field and
the MPF preview are kept, and the geotag reads back from EXIF GPS and DJI XMP with exifread, our reader, Pillow and
exiftool (where installed)."""

from __future__ import annotations

import math
import re
from datetime import datetime, timezone

import exifread
import numpy as np
import pytest
from defusedxml import ElementTree as SafeET
from PIL import ExifTags, Image

from capture.geotag import Geotag
from capture.geotag_io import dji_xmp_fields, write_exif_copy
from capture.jpeg_segments import split_jpeg
from capture.logs.photos import DRONE_DJI_NS, read_photo
from capture.xmp_update import with_dji_fields
from tests.exiftool_helpers import exiftool, needs_exiftool, serious_warnings

REAL_PHOTOS = ("brighton_beach/images/DJI_0018.JPG", "p4m_rtk/images/DJI_0010.JPG")
CALIBRATION = ("DewarpData", "CalibratedFocalLength", "CalibratedOpticalCenterX", "CalibratedOpticalCenterY",
               "DewarpFlag")


def a_geotag(name: str, **changes) -> Geotag:
    """A geotag far from where the sample photos were taken (so nothing reads back by accident)."""
    values = dict(image_name=name, time_s=0.0, time_source="event", source="duml/event", lat_deg=-33.8568123456,
                  lon_deg=151.2152987654, height_above_takeoff_m=41.25, absolute_height_m=123.4567,
                  aircraft_ypr_deg=np.array([12.5, -3.25, 1.5]), gimbal_ypr_deg=np.array([12.0, -88.5, math.nan]),
                  enu_m=np.zeros(3), R_world_cam=None)
    return Geotag(**(values | changes))


def xmp_packet(path) -> bytes:
    with Image.open(path) as image:
        return image.info["xmp"]


def xmp_fields(packet: bytes) -> dict[str, str]:
    """Every attribute and simple element of an XMP packet, by namespace-qualified name ({ns}name -> text)."""
    root = SafeET.fromstring(packet[packet.find(b"<x:xmpmeta"):packet.rfind(b"</x:xmpmeta>") + 12])
    fields = {}
    for element in root.iter():
        fields.update(element.attrib)
        if len(element) == 0 and (element.text or "").strip():
            fields[element.tag] = element.text.strip()
    return fields


def exif_text(path) -> dict[str, str]:
    """exifread's tags (maker note decoded too) as text, the thumbnail's bytes left out."""
    with open(path, "rb") as handle:
        return {name: str(tag) for name, tag in exifread.process_file(handle, details=True).items()
                if name != "JPEGThumbnail"}


def ratio_value(tag) -> float:
    return float(tag.num) / float(tag.den)


def dms(tag) -> float:
    degrees, minutes, seconds = (ratio_value(v) for v in tag.values)
    return degrees + minutes / 60.0 + seconds / 3600.0


@pytest.fixture(params=REAL_PHOTOS, ids=["brighton_FC300S_mpf", "p4m_FC6360_calibrated"])
def copied(request, shared_data, tmp_path):
    source = shared_data / request.param
    target = tmp_path / source.name
    tag = a_geotag(source.name)
    write_exif_copy(tag, source, target)
    return source, target, tag


def test_the_compressed_image_and_every_other_segment_are_the_original_bytes(copied):
    source, target, _ = copied
    original, copy = source.read_bytes(), target.read_bytes()
    (old_head, old_image), (new_head, new_image) = split_jpeg(original), split_jpeg(copy)
    assert new_image == old_image and len(old_image) > 0.9 * len(original)  # SOS .. EOI (+ MPF preview)
    metadata = (b"\xff\xe1", b"\xff\xe2")  # EXIF/XMP APP1 (replaced), MPF APP2 (its sizes updated)
    assert [s for s in new_head if s[:2] not in metadata] == [s for s in old_head if s[:2] not in metadata]
    with Image.open(source) as before, Image.open(target) as after:
        assert np.array_equal(np.asarray(before), np.asarray(after))


def test_every_exif_tag_but_the_gps_ones_is_kept_and_the_gps_reads_back(copied):
    source, target, tag = copied
    before, after = exif_text(source), exif_text(target)
    kept = {name: text for name, text in before.items() if not name.startswith("GPS ") and name != "Image GPSInfo"}
    assert any(name.startswith("MakerNote ") for name in kept) and len(kept) > 50
    assert {name: after.get(name) for name in kept} == kept
    with open(target, "rb") as handle:
        gps = exifread.process_file(handle, details=False)
    assert (str(gps["GPS GPSLatitudeRef"]), str(gps["GPS GPSLongitudeRef"])) == ("S", "E")
    assert -dms(gps["GPS GPSLatitude"]) == pytest.approx(tag.lat_deg, abs=1e-9)  # 1e-9 deg: 0.1 mm
    assert dms(gps["GPS GPSLongitude"]) == pytest.approx(tag.lon_deg, abs=1e-9)
    assert str(gps["GPS GPSAltitudeRef"]) == "0"
    assert ratio_value(gps["GPS GPSAltitude"].values[0]) == pytest.approx(tag.absolute_height_m, abs=1e-5)


def test_every_xmp_field_is_kept_except_those_the_geotag_sets(copied):
    source, target, tag = copied
    before, after = xmp_fields(xmp_packet(source)), xmp_fields(xmp_packet(target))
    dji = "{" + DRONE_DJI_NS + "}"
    ours = {dji + name: text for name, text in dji_xmp_fields(tag).items()}
    assert after == before | ours
    assert dji + "GimbalRollDegree" not in ours and after[dji + "GimbalRollDegree"] == "+0.00"  # unknown: kept
    if "p4m" in str(source):
        assert {dji + name for name in CALIBRATION} <= set(after)  # DJI's lens calibration survives
    assert len(xmp_packet(target)) == len(xmp_packet(source))  # the edit took its room from the packet's padding
    values = read_photo(target).values  # XMP (8 decimals) wins over EXIF there
    assert (values["lat_deg"], values["lon_deg"]) == pytest.approx((tag.lat_deg, tag.lon_deg), abs=5e-9)
    assert values["absolute_height_m"] == pytest.approx(tag.absolute_height_m, abs=1e-6)
    assert values["gimbal_pitch_deg"] == pytest.approx(tag.gimbal_ypr_deg[1])


def test_the_mpf_preview_is_kept_and_its_index_follows_the_grown_header(shared_data, tmp_path):
    source = shared_data / REAL_PHOTOS[0]
    target = tmp_path / source.name
    write_exif_copy(a_geotag(source.name), source, target)
    with Image.open(source) as before, Image.open(target) as after:
        assert before.format == after.format == "MPO" and after.n_frames == 2
        old, new = before.mpinfo[0xB002], after.mpinfo[0xB002]
        # the first image's length grows with the header (DJI's own value is 8192 short of SOI..EOI: it leaves
        # its XMP segment out, so it is shifted, not recomputed); the preview's offset counts from the MPF
        # segment, which moved with it
        grown = target.stat().st_size - source.stat().st_size
        assert grown > 0 and new[0]["Size"] == old[0]["Size"] + grown
        assert new[1]["DataOffset"] == old[1]["DataOffset"] and new[1]["Size"] == old[1]["Size"]
        before.seek(1)
        after.seek(1)
        assert np.array_equal(np.asarray(before), np.asarray(after))  # the preview, found by its MPF offset


def test_a_photo_without_gps_or_xmp_gets_both_and_keeps_its_time(tmp_path):
    exif = Image.Exif()
    exif.get_ifd(ExifTags.IFD.Exif)[ExifTags.Base.DateTimeOriginal] = "2024:05:01 10:00:18"
    source, target = tmp_path / "in.jpg", tmp_path / "out.jpg"
    Image.new("RGB", (16, 12), (90, 120, 60)).save(source, exif=exif)
    tag = a_geotag("in.jpg", absolute_height_m=-12.5)
    write_exif_copy(tag, source, target)
    info = read_photo(target)
    assert info.exif_time_s == datetime(2024, 5, 1, 10, 0, 18, tzinfo=timezone.utc).timestamp()
    assert (info.values["lat_deg"], info.values["lon_deg"]) == pytest.approx((tag.lat_deg, tag.lon_deg), abs=5e-9)
    assert info.values["absolute_height_m"] == pytest.approx(-12.5)  # below sea level: GPSAltitudeRef 1
    assert info.values["aircraft_yaw_deg"] == pytest.approx(12.5)  # from the new XMP packet
    bare = tmp_path / "bare.jpg"
    Image.new("RGB", (16, 12)).save(bare)  # JFIF only: no EXIF at all
    write_exif_copy(tag, bare, tmp_path / "bare_out.jpg")
    assert read_photo(tmp_path / "bare_out.jpg").values["lat_deg"] == pytest.approx(tag.lat_deg, abs=5e-9)


def test_xmp_fields_are_set_in_either_form_under_any_prefix_and_aliases_follow():
    packet = ('<?xpacket begin="" id="W5M0MpCehiHzreSzNTczkc9d"?><x:xmpmeta xmlns:x="adobe:ns:meta/">'
              '<rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
              f'<rdf:Description rdf:about="" xmlns:d="{DRONE_DJI_NS}" d:GpsLongtitude="1.0" d:Keep="x &amp; y">'
              '<d:AbsoluteAltitude>+10.0</d:AbsoluteAltitude></rdf:Description></rdf:RDF></x:xmpmeta>'
              '<?xpacket end="w"?>').encode()
    fields = xmp_fields(with_dji_fields(packet, {"GpsLongitude": "+2.5", "AbsoluteAltitude": "+20.0",
                                                 "RelativeAltitude": "a<b"}))
    dji = "{" + DRONE_DJI_NS + "}"
    assert fields == {dji + "GpsLongtitude": "+2.5", dji + "Keep": "x & y", dji + "AbsoluteAltitude": "+20.0",
                      dji + "RelativeAltitude": "a<b", "{http://www.w3.org/1999/02/22-rdf-syntax-ns#}about": ""}
    with pytest.raises(ValueError, match="no rdf:RDF"):
        with_dji_fields(b"<x:xmpmeta xmlns:x='adobe:ns:meta/'/>", {"GpsLatitude": "1"})


SCAN = b"\xff\xda\x00\x08\x01\x01\x00\x00\x3f\x00\x00\xff\xd9"  # a scan header, one byte of data, EOI


@pytest.mark.parametrize("data, message", [
    (b"\xff\xd8\xff\xe1\x10\x00Exif", "JPEG: the segment at byte 2 runs past the end of the file"),
    (b"\xff\xd8\xff\xe1\x00\x10Exif\x00\x00II*\x00\x0f\x27\x00\x00" + SCAN,
     "EXIF: IFD offset 9999 outside the 8-byte block"),
    (b"\xff\xd8\xff\xe1\x00\x10Exif\x00\x00XX*\x00\x08\x00\x00\x00" + SCAN, "EXIF: no TIFF header"),
    (b"\xff\xd8\xff\xd9", "JPEG: no image data"),
], ids=["segment_past_the_end", "ifd_outside_the_block", "no_tiff_header", "no_scan"])
def test_a_damaged_photo_is_refused_naming_it(tmp_path, data, message):
    source = tmp_path / "cut.jpg"
    source.write_bytes(data)
    with pytest.raises(ValueError, match=rf"cut\.jpg: {re.escape(message)}"):
        write_exif_copy(a_geotag("cut.jpg"), source, tmp_path / "out.jpg")
    assert not (tmp_path / "out.jpg").exists()


@needs_exiftool
def test_exiftool_reads_the_copy_and_finds_nothing_new_to_warn_about(copied):
    source, target, tag = copied
    assert serious_warnings(target) == serious_warnings(source) == []
    lat, lon, alt = (float(v) for v in exiftool("-n", "-s3", "-GPSLatitude#", "-GPSLongitude#", "-GPSAltitude#",
                                                  target).split())
    assert (lat, lon, alt) == pytest.approx((tag.lat_deg, tag.lon_deg, tag.absolute_height_m), abs=1e-6)
    preview = exiftool("-b", "-PreviewImage", source, binary=True)  # the MPF preview (brighton), none (p4m)
    assert exiftool("-b", "-PreviewImage", target, binary=True) == preview
