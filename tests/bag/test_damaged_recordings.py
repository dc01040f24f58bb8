"""Recordings damaged or cut short, and replays or videos stopped on the way: a chunk failing its checksum
is one line (exit 2), a file cut short replays up to its last whole record and says so (its end recorded as
stopped there), a map file a recording names is never opened, and Ctrl-C exits 130 keeping what was written
(a video already there is not replaced by half of a new one)."""

from __future__ import annotations

import io
import json
import zlib
from pathlib import Path

import pytest
import zstandard
from click.testing import CliRunner
from mcap.writer import CompressionType

from robotexp.bag import replay as replay_module
from robotexp.cli import main
from robotexp.output.results import read_jsonl

import crafted_bags as crafted

_CHUNK, _METADATA, _DATA_END = 0x06, 0x0C, 0x0F


def _top_records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, op, length) of each top-level record of an MCAP file."""
    out, at = [], 8
    while at + 9 <= len(data):
        op, length = data[at], int.from_bytes(data[at + 1:at + 9], "little")
        out.append((at, op, length))
        at += 9 + length
        if op == 0x02:          # the footer
            break
    return out


def _string(body: bytes, at: int) -> tuple[str, int]:
    n = int.from_bytes(body[at:at + 4], "little")
    return body[at + 4:at + 4 + n].decode(), at + 4 + n


def _with_chunk_records_changed(data: bytes, change) -> bytes:   # noqa: ANN001
    """`data` with the first chunk's records (decompressed) passed through `change`, compressed again and
    stored with the chunk's old CRC (as a flipped bit on a disk would leave it)."""
    for at, op, length in _top_records(data):
        if op != _CHUNK:
            continue
        body = data[at + 9:at + 9 + length]
        head = body[:24]                                  # start, end times; the uncompressed size
        crc = body[24:28]
        compression, p = _string(body, 28)
        n = int.from_bytes(body[p:p + 8], "little")
        records = zstandard.ZstdDecompressor().decompress(body[p + 8:p + 8 + n], max_output_size=2**27)
        assert zlib.crc32(records).to_bytes(4, "little") == crc
        changed = change(records)
        packed = zstandard.ZstdCompressor().compress(changed)
        new = (head[:16] + len(changed).to_bytes(8, "little") + crc + len(compression).to_bytes(4, "little")
               + compression.encode() + len(packed).to_bytes(8, "little") + packed)
        return data[:at] + bytes([_CHUNK]) + len(new).to_bytes(8, "little") + new + data[at + 9 + length:]
    raise AssertionError("no chunk")


def test_a_chunk_failing_its_checksum_is_one_line(tmp_path: Path) -> None:
    good = crafted.write(tmp_path / "good.mcap", compression=CompressionType.ZSTD, ticks=20)
    data = good.read_bytes()
    bad = tmp_path / "bad.mcap"
    # one byte of the last record's data flipped: the chunk still decompresses and parses
    bad.write_bytes(_with_chunk_records_changed(data, lambda r: r[:-3] + bytes([r[-3] ^ 0x40]) + r[-2:]))
    for args in (["replay", str(bad), "-o", str(tmp_path / "out")], ["video", str(bad), "-o", str(tmp_path / "v.gif")]):
        res = CliRunner().invoke(main, args)
        assert res.exit_code == 2, res.output
        (line,) = res.stderr.splitlines()
        assert str(bad) in line and "fails its checksum" in line and "damaged" in line, line
    # the same change with the CRC made again reads (the check is the CRC's, not the byte's)
    res = CliRunner().invoke(main, ["replay", str(good), "-o", str(tmp_path / "ok")])
    assert res.exit_code == 0, res.output


def test_a_length_damaged_past_the_data_is_not_read_and_one_before_it_is_a_cut(tmp_path: Path,
                                                                              caplog: pytest.LogCaptureFixture) -> None:
    """A record's length set to 2^56: in the summary (after the data end record, which one pass does not need)
    the recording replays whole; before the messages, the file ends there as one cut short."""
    good = crafted.write(tmp_path / "good.mcap", ticks=20)
    data = good.read_bytes()
    records = _top_records(data)
    (end,) = [i for i, (_, op, _) in enumerate(records) if op == _DATA_END]
    huge = (2**56).to_bytes(8, "little")
    summary = tmp_path / "summary.mcap"
    at = records[end + 1][0]
    summary.write_bytes(data[:at + 1] + huge + data[at + 9:])
    res = CliRunner().invoke(main, ["replay", str(summary), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "cut short" not in caplog.text
    (rec,) = read_jsonl(tmp_path / "out" / "results.jsonl")
    assert rec["reason"] != "stopped" and rec["robot_time_s"] >= 1.9
    # an unknown record (op 0x80, MCAP's private range) claiming 2^56 bytes before the messages: the file
    # ends there, before any scan
    (first,) = [at for at, op, _ in records if op == _CHUNK]
    inside = tmp_path / "inside.mcap"
    inside.write_bytes(data[:first] + bytes([0x80]) + huge + data[first:])
    res = CliRunner().invoke(main, ["replay", str(inside), "-o", str(tmp_path / "out2")])
    assert res.exit_code == 2, res.output
    (line,) = res.stderr.splitlines()
    assert str(inside) in line and "before its first /scan and /odom (cut short)" in line, line


def test_a_recording_cut_short_replays_to_its_cut_and_says_so(recorded: tuple[Path, dict], tmp_path: Path,
                                                              caplog: pytest.LogCaptureFixture) -> None:
    bag, _ = recorded
    data = bag.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:int(len(data) * 0.8)])
    res = CliRunner().invoke(main, ["replay", str(cut), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "without its end (cut short" in caplog.text
    (rec,) = read_jsonl(tmp_path / "out" / "results.jsonl")
    assert rec["end"] == "stopped" and "cut short" in rec["reason"] and rec["completed"] is False
    assert 0 < rec["robot_time_s"] < 25.0
    tiny = tmp_path / "tiny.mcap"
    tiny.write_bytes(data[:900])
    res = CliRunner().invoke(main, ["replay", str(tiny), "-o", str(tmp_path / "out2")])
    assert res.exit_code == 2 and "before its first /scan and /odom (cut short)" in res.stderr, res.output


def test_a_map_file_the_recording_names_is_not_opened(recorded: tuple[Path, dict], tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch,
                                                      caplog: pytest.LogCaptureFixture) -> None:
    """world_source naming a map file (whose image could be any file): a replay at another cell does not
    open it, and says how to give the map; with --world the user's map is used."""
    bag, _ = recorded
    data = bag.read_bytes()
    secret = tmp_path / "secret.yaml"
    secret.write_text("image: /etc/hostname\nresolution: 0.05\norigin: [0, 0, 0]\n")
    out = io.BytesIO()
    out.write(data[:8])
    for at, op, length in _top_records(data):
        record = data[at:at + 9 + length]
        if op == _METADATA:
            body = record[9:]
            name, p = _string(body, 0)
            if name == "robotexp.run":
                pairs = body[p + 4:]
                key, q = _string(pairs, 0)
                text, _ = _string(pairs, q)
                meta = json.loads(text)
                meta["world_source"] = str(secret)
                text2 = json.dumps(meta).encode()
                pairs2 = len(key).to_bytes(4, "little") + key.encode() + len(text2).to_bytes(4, "little") + text2
                body2 = body[:p] + len(pairs2).to_bytes(4, "little") + pairs2
                record = bytes([op]) + len(body2).to_bytes(8, "little") + body2
        out.write(record)
    out.write(data[8 + sum(9 + n for _, _, n in _top_records(data)):])
    named = tmp_path / "named.mcap"
    named.write_bytes(out.getvalue())
    opened: list[str] = []
    import robotexp.world.loader as loader

    original = loader.load_world
    monkeypatch.setattr(loader, "load_world", lambda spec: opened.append(spec) or original(spec))
    res = CliRunner().invoke(main, ["replay", str(named), "-o", str(tmp_path / "out"), "--cell", "50"])
    assert res.exit_code == 0, res.output
    assert opened == [] and "a replay does not open by itself" in caplog.text and "--world" in caplog.text
    res = CliRunner().invoke(main, ["replay", str(named), "-o", str(tmp_path / "out"), "--cell", "50", "--world",
                                    str(tmp_path / "nope.yaml")])
    assert res.exit_code == 2 and "--world" in res.stderr


def _interrupt_at(monkeypatch: pytest.MonkeyPatch, tick: int) -> None:
    """Ctrl-C as the replay reads tick `tick` (the run loop ends the run there and writes it)."""
    read = replay_module.ReplayRobot._read

    def _read(self):  # noqa: ANN001, ANN202
        if self._i == tick:
            raise KeyboardInterrupt
        return read(self)
    monkeypatch.setattr(replay_module.ReplayRobot, "_read", _read)


def test_ctrl_c_in_a_replay_exits_130_with_its_record(recorded: tuple[Path, dict], tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    bag, _ = recorded
    _interrupt_at(monkeypatch, 100)
    res = CliRunner().invoke(main, ["replay", str(bag), "-o", str(tmp_path / "out")])
    assert res.exit_code == 130, res.output
    assert "replay interrupted at robot time" in res.stderr and "robotexp: interrupted" in res.stderr
    (rec,) = read_jsonl(tmp_path / "out" / "results.jsonl")
    assert rec["end"] == "interrupted"


def test_ctrl_c_in_a_video_keeps_the_video_there(recorded: tuple[Path, dict], tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    bag, _ = recorded
    video = tmp_path / "v.gif"
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(video), "--every", "2"])
    assert res.exit_code == 0, res.output
    whole = video.read_bytes()
    _interrupt_at(monkeypatch, 100)
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(video), "--every", "2"])
    assert res.exit_code == 130, res.output
    assert "was not written (the one there is kept)" in res.stderr
    assert video.read_bytes() == whole and sorted(p.name for p in tmp_path.iterdir()) == ["v.gif"]


def test_a_video_that_cannot_be_written_fails(recorded: tuple[Path, dict], tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    bag, _ = recorded
    (tmp_path / "afile").write_text("x")
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / "afile" / "v.gif")])
    assert res.exit_code == 2 and "is a file, not a folder" in res.stderr
    from robotexp.output import video as video_module

    def full(self, px):  # noqa: ANN001, ANN202
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(video_module._GifStream, "append", full)
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / "v.gif")])
    assert res.exit_code != 0 and "video:" not in res.stdout and "No space left on device" in res.stderr
    assert not (tmp_path / "v.gif").exists() and not list(tmp_path.glob(".*partial*"))
