"""User JSON: deep nesting is a JSONDecodeError (so every reader's own handling applies), files are named."""

import json

import pytest

from cliutil.errors import BadInput
from cliutil.jsonfile import is_finite_number, loads_json, read_json


def test_nesting_python_can_read_reads_and_deeper_is_a_decode_error():
    assert loads_json("[" * 500 + "]" * 500) == json.loads("[" * 500 + "]" * 500)
    with pytest.raises(json.JSONDecodeError, match="nested deeper than"):
        loads_json(b"{\"a\": " * 100_000 + b"1" + b"}" * 100_000)


@pytest.mark.parametrize("content, message", [
    ("[" * 100_000, r"x\.json: invalid JSON at line 1: nested deeper than"),
    ('{"a": 1,\n "b": }', r"x\.json: invalid JSON at line 2: Expecting value"),
    (b"\xff\xfe{}", r"x\.json: not UTF-8 text \(byte 0"),
])
def test_read_json_names_the_file_and_line(tmp_path, content, message):
    path = tmp_path / "x.json"
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(BadInput, match=message):
        read_json(path)
    path.write_text('{"origin": {"lat0_deg": 1}}')
    assert read_json(path) == {"origin": {"lat0_deg": 1}}


def test_a_finite_number_is_what_the_parser_gives_for_a_finite_number_only():
    parsed = loads_json('[0, -3, 1.5, 1e308, "1.5", true, false, null, NaN, Infinity, -Infinity, [1], {"a": 1}]')
    assert [is_finite_number(value) for value in parsed] == [True] * 4 + [False] * 9
