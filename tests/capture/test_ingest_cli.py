"""aerostereo-ingest: decode a real pcap, record a live socket link, list devices, reject bad input."""

import csv
import socket
import threading
import time

import pytest
from duml_vectors import frame

from capture import cli
from capture.fakeusb import FakeUsbBackend
from capture.raw import index_path, read_index

pytestmark = pytest.mark.timeout(60)


def test_decode_real_pcap_to_csv(shared_data, tmp_path, capsys):
    pcap = shared_data / "dji" / "dji-packet-dumps__p3x_ofdm_to_center_run1.pcap"
    out = tmp_path / "telemetry.csv"
    assert cli.main(["decode", str(pcap), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "4651 packets" in printed and "osd_general 227" in printed and "gimbal_params 1168" in printed
    assert "bad_packet_crc 0" in printed
    with open(out, newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 227 + 18 + 1168
    osd = [r for r in rows if r["kind"] == "osd_general"]
    assert all(r["latitude_deg"] == "0.0" and r["has_fix"] == "0" for r in osd)
    assert rows[0]["utc_time"].startswith("2017-12-20T") and rows[0]["utc_time"].endswith("Z")
    assert not list(tmp_path.glob(".*.tmp*"))  # written through a temporary name


def test_decode_raw_capture_with_index_uses_arrival_times(tmp_path, capsys):
    from capture.raw import RawCaptureWriter
    import datetime as dt

    path = tmp_path / "live.duml"
    osd = frame("7_osd_general_p3x")
    t0 = dt.datetime(2024, 1, 2, 3, 4, 5, tzinfo=dt.timezone.utc)
    with RawCaptureWriter(path) as writer:
        writer.append(t0, 1.0, b"\x00garbage" + osd[:20])
        writer.append(t0 + dt.timedelta(seconds=0.25), 1.25, osd[20:])
    out = tmp_path / "t.csv"
    assert cli.main(["decode", str(path), "--out", str(out)]) == 0
    [row] = list(csv.DictReader(open(out, newline="")))
    assert row["utc_time"] == "2024-01-02T03:04:05.250000Z"  # when the frame's last byte arrived
    assert row["offset"] == "8" and float(row["latitude_deg"]) == pytest.approx(54.3738781)
    assert "no_sync 8" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["decode", "MISSING.duml", "--out", "x.csv"], "MISSING.duml: not found; expected a raw capture"),
    (["record", "--port", "usb:zz:1", "--out", "x.duml"], "expected usb:VID:PID"),
    (["record", "--port", "/dev/no-such-tty-aerostereo", "--duration", "1", "--out", "x.duml"], "cannot open serial"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # no half-made output


def test_decode_of_a_non_duml_file_fails_cleanly(tmp_path, capsys):
    text = tmp_path / "notes.txt"
    text.write_text("hello, this is not telemetry\n" * 20)
    assert cli.main(["decode", str(text), "--out", str(tmp_path / "t.csv")]) == 2
    assert "no DUML frame found" in capsys.readouterr().err
    assert not (tmp_path / "t.csv").exists()


def test_record_from_a_socket_link(tmp_path, capsys):
    server = socket.create_server(("127.0.0.1", 0))
    data = frame("7_osd_general_p3x") + frame("8_gimbal_params")

    def serve():
        connection, _ = server.accept()
        time.sleep(0.2)
        for _ in range(5):
            connection.sendall(data)
            time.sleep(0.05)
        time.sleep(1.5)
        connection.close()

    thread = threading.Thread(target=serve)
    thread.start()
    out = tmp_path / "live.duml"
    port = f"socket://127.0.0.1:{server.getsockname()[1]}"
    assert cli.main(["record", "--port", port, "--duration", "1.0", "--out", str(out)]) == 0
    thread.join()
    server.close()
    assert out.read_bytes() == data * 5
    assert read_index(index_path(out)).lengths.sum() == len(data) * 5
    err = capsys.readouterr().err
    assert "10 packets" in err and "54.373878,18.561662" in err


def test_list_shows_the_fake_usb_device(capsys):
    assert cli.run_list(None, usb_backend=FakeUsbBackend(product_id=0x001F)) == 0
    out = capsys.readouterr().out
    assert "usb:2ca3:001f" in out and "DUML bulk IN 0x85" in out and "serial ports:" in out


def test_extension_modules_are_optional_and_subcommands_listed():
    parser = cli.build_parser()
    choices = parser._subparsers._group_actions[0].choices
    assert {"record", "decode", "list"} <= set(choices)


def test_kill_9_mid_capture_leaves_a_readable_prefix(tmp_path):
    import os
    import signal
    import subprocess
    import sys

    from capture.raw import read_capture_chunks

    server = socket.create_server(("127.0.0.1", 0))
    data = (frame("7_osd_general_p3x") + frame("8_gimbal_params")) * 400
    out = tmp_path / "killed.duml"
    env = dict(os.environ, PYTHONPATH=str(cli.Path(cli.__file__).resolve().parents[1]))
    process = subprocess.Popen([sys.executable, "-m", "capture", "record", "--port",
                                f"socket://127.0.0.1:{server.getsockname()[1]}", "--out", str(out)],
                               env=env, stderr=subprocess.DEVNULL, stdout=subprocess.DEVNULL)
    connection, _ = server.accept()
    time.sleep(0.5)
    for start in range(0, len(data), 97):
        connection.sendall(data[start:start + 97])
        time.sleep(0.0002)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < len(data) // 2):
        time.sleep(0.001)
    process.send_signal(signal.SIGKILL)
    process.wait()
    connection.close()
    server.close()
    kept = out.read_bytes()
    assert len(kept) >= len(data) // 2 and data.startswith(kept)  # every byte received, in order
    assert b"".join(chunk[2] for chunk in read_capture_chunks(out)) == kept
    index = read_index(index_path(out))  # the kill may fall between a data flush and its index line
    assert index.offsets.tolist() == [sum(index.lengths[:i]) for i in range(len(index.offsets))]
    assert index.lengths.sum() <= len(kept)


def test_decode_output_is_shared_readable_in_a_new_folder(tmp_path):
    capture = tmp_path / "live.duml"
    capture.write_bytes(frame("7_osd_general_p3x"))
    out = tmp_path / "new" / "t.csv"
    assert cli.main(["decode", str(capture), "--out", str(out)]) == 0
    assert out.stat().st_mode & 0o777 == 0o644 and len(out.read_text().splitlines()) == 2


def test_decode_onto_a_folder_names_the_target(tmp_path, capsys):
    capture = tmp_path / "live.duml"
    capture.write_bytes(frame("7_osd_general_p3x"))
    (tmp_path / "t.csv").mkdir()
    assert cli.main(["decode", str(capture), "--out", str(tmp_path / "t.csv")]) == 2
    [error] = capsys.readouterr().err.splitlines()  # refused before the note that live.duml.idx is missing
    assert error.endswith(f"--out {tmp_path / 't.csv'}: is a folder; expected the name of a file to write")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["live.duml", "t.csv"]  # no temporary left


@pytest.mark.parametrize("duration", ["nan", "inf", "-1", "0", "soon"])
def test_record_duration_must_be_a_positive_finite_number(tmp_path, capsys, duration):
    assert cli.main(["record", "--port", "loop://", "--duration", duration, "--out", str(tmp_path / "x.duml")]) == 2
    assert not list(tmp_path.iterdir())
    assert (f"aerostereo-ingest record: error: argument --duration: expected a positive number, got {duration!r}"
            in capsys.readouterr().err)


def test_hid_port_with_bad_ids_shows_a_hid_example(capsys):
    assert cli.main(["record", "--port", "hid:dji", "--out", "x.duml"]) == 2
    assert "expected hid:VID:PID with hex ids, e.g. hid:2ca3:001f" in capsys.readouterr().err


def test_decode_of_a_pcap_cut_short_keeps_its_records_and_notes_the_cut(shared_data, tmp_path, capsys):
    whole = (shared_data / "dji" / "dji-packet-dumps__p3x_ofdm_to_center_run1.pcap").read_bytes()
    pcap = tmp_path / "killed.pcap"
    pcap.write_bytes(whole[:-3])
    assert cli.main(["decode", str(pcap), "--out", str(tmp_path / "t.csv")]) == 0
    captured = capsys.readouterr()
    assert "4650 packets" in captured.out  # the last frame lost its CRC bytes, the rest decode
    assert f"note: {pcap}: truncated record at byte " in captured.err


def test_decode_of_a_pcap_with_a_corrupt_record_length_keeps_every_row_and_names_the_byte(shared_data, tmp_path,
                                                                                          capsys):
    original = shared_data / "dji" / "dji-packet-dumps__p3x_ofdm_to_center_run3.pcap"
    data = bytearray(original.read_bytes())
    record = 24 + 16 + int.from_bytes(data[24 + 8:24 + 12], "little")  # the second record's header
    data[record + 8:record + 12] = (10 ** 9).to_bytes(4, "little")
    pcap = tmp_path / "corrupt.pcap"
    pcap.write_bytes(bytes(data))
    assert cli.main(["decode", str(original), "--out", str(tmp_path / "intact.csv")]) == 0
    assert cli.main(["decode", str(pcap), "--out", str(tmp_path / "t.csv")]) == 0
    captured = capsys.readouterr()
    assert f"note: {pcap}: corrupt record at byte {record} (captured length 1000000000" in captured.err
    with open(tmp_path / "intact.csv", newline="") as intact, open(tmp_path / "t.csv", newline="") as damaged:
        intact_rows, damaged_rows = list(csv.DictReader(intact)), list(csv.DictReader(damaged))
    assert len(damaged_rows) == len(intact_rows) == 2330
    differing = [(a, b) for a, b in zip(intact_rows, damaged_rows) if a != b]
    assert len(differing) <= 1  # the corrupt record's own message, if telemetry, lost its time only
    assert all(b["utc_time"] == "" and {**a, "utc_time": "", "monotonic_s": ""} == b for a, b in differing)
    assert len({r["utc_time"] for r in damaged_rows}) > 2000  # not one timestamp for everything after it


def test_decode_of_a_wireshark_pcapng_gives_the_rows_and_times_of_the_same_pcap(shared_data, tmp_path):
    import dpkt

    from capture.transports import read_pcap

    pcap = shared_data / "dji" / "dji-packet-dumps__p3x_ofdm_to_center_run1.pcap"
    pcapng = tmp_path / "run1.pcapng"
    with open(pcapng, "wb") as handle:
        writer = dpkt.pcapng.Writer(handle, snaplen=65535, linktype=150)
        for record in read_pcap(pcap):
            writer.writepkt(record.data, ts=record.receive_time_utc.timestamp())
    assert cli.main(["decode", str(pcap), "--out", str(tmp_path / "pcap.csv")]) == 0
    assert cli.main(["decode", str(pcapng), "--out", str(tmp_path / "pcapng.csv")]) == 0
    assert (tmp_path / "pcapng.csv").read_bytes() == (tmp_path / "pcap.csv").read_bytes()
