"""Damaged bags through the command line (`activetrack_bringup.cli.main`): truncation at many
offsets, bytes flipped at many positions (in every kind of MCAP record), deleted or garbled
metadata.yaml, missing/empty/garbage .mcap files, bad paths, unknown message types.

For every case: the exit code is 0 or 2, never a traceback, at most one ``error:`` line; a
message that is read back is byte-identical to one of the original bag (nothing is ever
decoded from damaged bytes); a case the commands do not report is provably harmless (every
message reads back, identical); `bag recover` either refuses (rc 2) or leaves a bag that
`bag info` calls intact and rosbags reads. The table of cases is printed (pytest -s).
"""

import shutil
import struct
from collections import Counter
from pathlib import Path

import pytest
import yaml
from rosbags.rosbag2 import Reader

from activetrack_bringup.bag import graph_schemas
from activetrack_bringup.bag_io import BagError, Rosbag2Writer, TopicSpec, open_bag
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.graph import GRAPH_TOPICS

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """A recorded run's bag and its messages, (topic, log time, bytes), read two ways."""
    bag = run_graph(SCENARIO, run_dir=tmp_path_factory.mktemp("orig"), plots=False).bag
    with open_bag(bag) as b:
        assert b.intact
        ours = [(t, ts, bytes(d)) for t, ts, d in b.messages()]
    with Reader(bag) as reader:  # independent reference
        theirs = sorted((c.topic, ts, bytes(d)) for c, ts, d in reader.messages())
    assert sorted(ours) == theirs
    return bag, ours


def cli(capsys, *argv):
    try:
        rc = cli_main([str(a) for a in argv])
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    problems = []
    if "Traceback" in out + err:
        problems.append("traceback")
    if rc not in (0, 2):
        problems.append(f"rc {rc}")
    lines = err.splitlines()
    if any(not line.startswith(("warning: ", "error: ")) for line in lines):
        problems.append("stderr line that is neither warning nor error")
    errors = [line for line in lines if line.startswith("error: ")]
    if (rc == 2) != (len(errors) == 1) or len(errors) > 1:
        problems.append(f"rc {rc} with {len(errors)} error lines")
    return rc, out, err, problems


def top_records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, length) of the top-level records (independent of the package)."""
    out, pos = [], 8
    while pos + 9 <= len(data) - 8:
        op, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, op, length))
        if op == 0x02:
            break
        pos += 9 + length
    return out


def _flip(pos: int, mask: int = 0xFF):
    def mutate(bag: Path, mcap: Path):
        data = bytearray(mcap.read_bytes())
        data[pos] ^= mask
        mcap.write_bytes(data)

    return mutate


def _truncate(n: int):
    def mutate(bag: Path, mcap: Path):
        mcap.write_bytes(mcap.read_bytes()[:n])

    return mutate


def _meta_text(text: str | bytes):
    def mutate(bag: Path, mcap: Path):
        path = bag / "metadata.yaml"
        path.write_bytes(text if isinstance(text, bytes) else text.encode())

    return mutate


def _meta_edit(edit):
    def mutate(bag: Path, mcap: Path):
        path = bag / "metadata.yaml"
        doc = yaml.safe_load(path.read_text())
        edit(doc["rosbag2_bagfile_information"])
        path.write_text(yaml.safe_dump(doc))

    return mutate


def _meta_cut(fraction: float):
    def mutate(bag: Path, mcap: Path):
        path = bag / "metadata.yaml"
        text = path.read_bytes()
        path.write_bytes(text[: int(len(text) * fraction)])

    return mutate


def _unlink(name: str):
    def mutate(bag: Path, mcap: Path):
        (bag / name if name != "mcap" else mcap).unlink()

    return mutate


def _mcap_bytes(data: bytes):
    def mutate(bag: Path, mcap: Path):
        mcap.write_bytes(data)

    return mutate


def _mcap_dir(bag: Path, mcap: Path):
    mcap.unlink()
    mcap.mkdir()


def _double_counts(info):
    for t in info["topics_with_message_count"]:
        t["message_count"] = 2 * t["message_count"] + 1


def _cases(mcap_bytes: bytes) -> list[tuple[str, str, object]]:
    """(category, name, mutate(bag_dir, mcap_path)) of every case."""
    size = len(mcap_bytes)
    recs = top_records(mcap_bytes)
    first = {}
    for pos, op, length in recs:
        first.setdefault(op, []).append((pos, length))
    header_end = recs[0][0]
    defs, defs_len = first[0x06][0]
    chunk, chunk_len = first[0x06][min(2, len(first[0x06]) - 1)]
    index, _ = first[0x07][0]
    data_end, _ = first[0x0F][0]
    metadata, _ = first[0x0C][0]
    summary = data_end + 13
    footer = size - 37
    chunk_index, _ = first[0x08][0]  # the summary's first ChunkIndex record
    cases = []
    cuts = [1, 4, 8, 12, header_end, defs + 20, defs + defs_len // 2, defs + 9 + defs_len]
    cuts += [int(size * f / 20) for f in range(1, 20)]
    cuts += [chunk + 30, chunk + 9 + chunk_len, index + 10, data_end, data_end + 6, summary + 40]
    cuts += [footer, footer + 20, size - 8, size - 1]
    for n in sorted(set(cuts)):
        cases.append(("truncate", f"at {n}", _truncate(n)))
    flips = [int(size * f / 20) + 3 for f in range(20)]
    for pos in sorted(set(flips)):
        cases.append(("flip", f"0xff at {pos}", _flip(pos)))
    targeted = {
        "magic": 3,
        "header profile": header_end - 20,
        "definitions chunk opcode": defs,
        "definitions chunk length": defs + 1,
        "definitions chunk start time": defs + 9,
        "definitions chunk crc": defs + 9 + 24,
        "definitions chunk compression length": defs + 9 + 28,
        "definitions chunk records size": defs + 9 + 32,
        "definitions chunk schema text": defs + 200,
        "message chunk opcode": chunk,
        "message chunk length": chunk + 2,
        "message chunk end time": chunk + 9 + 8,
        "message chunk uncompressed size": chunk + 9 + 16,
        "message chunk crc": chunk + 9 + 25,
        "message chunk first record": chunk + 9 + 40,
        "message chunk data": chunk + chunk_len // 2,
        "message index opcode": index,
        "message index length": index + 1,
        "message index channel": index + 9,
        "message index time": index + 9 + 6 + 2,
        "message index offset": index + 9 + 6 + 9,
        "metadata record": metadata + 40,
        "data end crc": data_end + 9,
        "summary schema": summary + 30,
        "summary chunk index offset": chunk_index + 9 + 16,
        "summary statistics": footer - 200,
        "footer summary start": footer + 9,
        "footer summary offset start": footer + 17,
        "footer crc": footer + 25,
        "end magic": size - 2,
    }
    for name, pos in targeted.items():
        cases.append(("flip", name, _flip(pos, 0x01)))
    cases += [
        ("metadata", "deleted", _unlink("metadata.yaml")),
        ("metadata", "empty", _meta_text("")),
        ("metadata", "binary garbage", _meta_text(bytes(range(256)) * 4)),
        ("metadata", "not YAML", _meta_text("rosbag2_bagfile_information: {{{[\n")),
        ("metadata", "a list", _meta_text("- 1\n- 2\n")),
        ("metadata", "truncated 30%", _meta_cut(0.3)),
        ("metadata", "truncated 60%", _meta_cut(0.6)),
        ("metadata", "truncated 90%", _meta_cut(0.9)),
        ("metadata", "version 99", _meta_edit(lambda i: i.update(version=99))),
        (
            "metadata",
            "storage sqlite3",
            _meta_edit(lambda i: i.update(storage_identifier="sqlite3")),
        ),
        ("metadata", "storage foo", _meta_edit(lambda i: i.update(storage_identifier="foo"))),
        ("metadata", "no file list", _meta_edit(lambda i: i.pop("relative_file_paths"))),
        (
            "metadata",
            "file missing",
            _meta_edit(lambda i: i.update(relative_file_paths=["x.mcap"])),
        ),
        ("metadata", "compressed", _meta_edit(lambda i: i.update(compression_mode="file"))),
        (
            "metadata",
            "topics a string",
            _meta_edit(lambda i: i.update(topics_with_message_count="x")),
        ),
        ("metadata", "negative count", _meta_edit(lambda i: i.update(message_count=-5))),
        ("metadata", "stale counts", _meta_edit(_double_counts)),
        ("metadata", "a topic missing", _meta_edit(lambda i: i["topics_with_message_count"].pop())),
        ("mcap", "deleted", _unlink("mcap")),
        ("mcap", "empty", _mcap_bytes(b"")),
        ("mcap", "garbage", _mcap_bytes(bytes((i * 37) % 256 for i in range(4096)))),
        ("mcap", "magic only", _mcap_bytes(mcap_bytes[:8])),
        ("mcap", "magic and garbage", _mcap_bytes(mcap_bytes[:8] + b"\xaa" * 500)),
        ("mcap", "text file", _mcap_bytes(b"hello, this is not a bag\n")),
        ("mcap", "a directory", _mcap_dir),
    ]
    return cases


def test_damaged_bags_never_traceback_and_never_decode_damage(original, tmp_path, capsys):
    bag0, ref = original
    refset = set(ref)
    mcap_name = f"{bag0.name}.mcap"
    cases = _cases((bag0 / mcap_name).read_bytes())
    rows, problems = [], []
    for i, (category, name, mutate) in enumerate(cases):
        bag = tmp_path / f"c{i}" / bag0.name
        shutil.copytree(bag0, bag)
        mutate(bag, bag / mcap_name)
        where = f"{category} {name}"
        rc, out, err, p = cli(capsys, "bag", "info", bag)
        problems += [f"{where}: info: {x}" for x in p]
        detected = rc == 2 or "warning:" in err
        usable = out.startswith(f"bag {bag}:")
        try:
            with open_bag(bag) as b:
                got = [(t, ts, bytes(d)) for t, ts, d in b.messages()]
        except BagError:
            got = None  # refused: nothing readable (or not without `bag recover`)
        if (got is None) == usable:
            problems.append(f"{where}: info and the reader disagree on whether it is readable")
        got = got or []
        wrong = [m for m in got if m not in refset]
        if wrong:
            problems.append(f"{where}: {len(wrong)} messages read that are not the original's")
        lost = len(ref) - len(got)
        if not detected and got != ref:
            problems.append(f"{where}: undetected, and the messages differ")
        if lost and not detected:
            problems.append(f"{where}: {lost} messages lost without a report")
        rc_r, _, _, p = cli(capsys, "bag", "recover", bag)
        problems += [f"{where}: recover: {x}" for x in p]
        recovered = False
        if rc_r == 0:
            rc_i, _, err_i, p = cli(capsys, "bag", "info", bag)
            problems += [f"{where}: info after recover: {x}" for x in p]
            if i % 4 == 0:  # rosbags reads the recovered bag (a sample: it is slow)
                with Reader(bag) as reader:
                    after = sorted((c.topic, ts, bytes(d)) for c, ts, d in reader.messages())
            else:
                with open_bag(bag) as b:
                    after = sorted((t, ts, bytes(d)) for t, ts, d in b.messages())
            if rc_i != 0 or any(m not in refset for m in after):
                problems.append(f"{where}: recovered bag not intact ({err_i.strip()[:200]})")
            if category in ("flip", "truncate") and after != sorted(got):
                problems.append(f"{where}: recover kept {len(after)}, the reader {len(got)}")
            recovered = rc_i == 0
        rows.append((category, detected, usable, lost, recovered))
    # detected: reported (rc 2 or a warning); refused: an error, nothing shown; partial:
    # readable with messages skipped (reported); whole: readable with every message;
    # recovered: `bag recover` made it a bag that `bag info` calls intact.
    columns = ("cases", "detected", "refused", "partial", "whole", "recovered")
    table = Counter()
    for category, detected, usable, lost, recovered in rows:
        values = (True, detected, not usable, usable and lost > 0, usable and not lost, recovered)
        for key, value in zip(columns, values, strict=True):
            table[category, key] += bool(value)
            table["total", key] += bool(value)
    with capsys.disabled():
        print(f"\n{'damaged bags':<12} " + " ".join(columns))
        for category in ("truncate", "flip", "metadata", "mcap", "total"):
            print(f"{category:<12} " + " ".join(f"{table[category, k]:>{len(k)}}" for k in columns))
    assert len(rows) >= 72
    assert not problems, "\n".join(problems)
    # Every case is damage, and each is reported (a flip in a byte nothing reads would show
    # up above as undetected-and-identical, which is allowed; there is none).
    assert table["total", "detected"] == len(rows)


def _typed_bag(tmp_path, name, extra: list[TopicSpec], clock_count: int = 3) -> Path:
    schemas = graph_schemas([GRAPH_TOPICS[topics.CLOCK]])
    good = TopicSpec(topics.CLOCK, GRAPH_TOPICS[topics.CLOCK], *schemas[GRAPH_TOPICS[topics.CLOCK]])
    specs = ([good] if clock_count else []) + extra
    writer = Rosbag2Writer(tmp_path / name, specs, state="closed")
    clock = bytes.fromhex("000100000000000000000000")  # CDR of an empty Clock
    for i in range(clock_count):
        writer.write(writer.channel_ids[topics.CLOCK], 1000 + i, clock)
    for spec in extra:
        writer.write(writer.channel_ids[spec.topic], 2000, b"\x00\x01\x00\x00\x01\x02\x03\x04")
    writer.close()
    return tmp_path / name


def test_unknown_types_are_skipped_with_one_warning(tmp_path, capsys):
    unknown = TopicSpec("/weird", "nonexistent_msgs/msg/Foo", "int32 a\n", "RIHS01_" + "0" * 64)
    json_enc = TopicSpec(
        "/json", "std_msgs/msg/String", "string data\n", "", serialization_format="json"
    )
    bad_name = TopicSpec("/badname", "not a type", "int32 a\n", "")
    old_def = TopicSpec(
        topics.TRACKS, GRAPH_TOPICS[topics.TRACKS], "float64 x\n", "RIHS01_" + "1" * 64
    )
    bag = _typed_bag(tmp_path, "mixed", [unknown, json_enc, bad_name, old_def])
    rc, out, err, p = cli(capsys, "bag", "info", bag)
    assert not p and rc == 0 and f"bag {bag}: 7 messages" in out
    for topic in ("/weird", "/json", "/badname", topics.TRACKS):
        assert sum(topic + " " in line for line in err.splitlines()) == 1, (topic, err)
    rc, out, err, p = cli(capsys, "play", bag, "--rate", "1000")
    assert not p and rc == 0 and "published 3 messages" in out  # the clock only
    assert len(err.splitlines()) == 4
    rc, out, err, p = cli(capsys, "play", bag, "--topics", "/weird")
    assert not p and rc == 2 and "cannot be played" in err
    only = _typed_bag(tmp_path, "only_unknown", [unknown], clock_count=0)
    rc, out, err, p = cli(capsys, "play", only)
    assert not p and rc == 2 and "no playable topic" in err


def test_damaged_bags_through_play_retrack_recover_and_record(original, tmp_path, capsys):
    bag0, _ = original
    mcap_name = f"{bag0.name}.mcap"
    data = (bag0 / mcap_name).read_bytes()
    chunk = [pos for pos, op, _ in top_records(data) if op == 0x06][1]  # a message chunk
    cases = {
        "missing path": None,
        "no metadata": _unlink("metadata.yaml"),
        "garbage metadata": _meta_text("{{{"),
        "sqlite3 storage": _meta_edit(lambda i: i.update(storage_identifier="sqlite3")),
        "empty mcap": _mcap_bytes(b""),
        "corrupt chunk": _flip(chunk + 200),
        "killed (truncated)": _truncate(len(data) * 2 // 3),
    }
    # Every damaged bag is refused (rc 2) unless --skip-damaged; a truncated one too.
    expected_play = {}
    for name, mutate in cases.items():
        bag = tmp_path / name.replace(" ", "_") / bag0.name
        if mutate is not None:
            shutil.copytree(bag0, bag)
            mutate(bag, bag / mcap_name)
        rc, out, err, p = cli(capsys, "play", bag, "--rate", "1000")
        assert not p, (name, p)
        assert rc == expected_play.get(name, 2), (name, err)
        if name == "corrupt chunk":
            assert f"{bag / mcap_name}: corrupt chunk at offset {chunk} (CRC mismatch;" in err
        if name in ("corrupt chunk", "killed (truncated)"):
            assert "--skip-damaged" in err and "bag recover" in err
            rc, out, err, p = cli(capsys, "play", bag, "--rate", "1000", "--skip-damaged")
            assert not p and rc == 0 and "warning:" in err and "published" in out
        if name == "killed (truncated)":
            assert "no summary" in err and "published" in out
        rc, out, err, p = cli(capsys, "bag", "retrack", bag, "--scenario", SCENARIO)
        assert not p, (name, p)
        assert rc in (0, 2)
        if name == "corrupt chunk":
            assert rc == 2 and "retrack needs every scan" in err
        if name == "killed (truncated)":  # refused, unless told to take the epochs it holds
            assert rc == 2 and "cut off" in err and "--skip-damaged" in err
            rc, out, err, p = cli(
                capsys, "bag", "retrack", bag, "--scenario", SCENARIO, "--skip-damaged"
            )
            assert not p and rc in (0, 2), (rc, err)
            assert rc == 2 or "retracking epochs 1.." in err
            # `track` on the bag's scans alike: refused, unless told to take what it holds.
            out_dir = bag.parent / "tracked"
            rc, out, err, p = cli(capsys, "track", bag, "--config", SCENARIO, "--out", out_dir)
            assert not p and rc == 2 and "cut off" in err and "--skip-damaged" in err, err
            assert not out_dir.exists()
            rc, out, err, p = cli(
                capsys, "track", bag, "--config", SCENARIO, "--out", out_dir, "--skip-damaged"
            )
            assert not p and rc == 0 and (out_dir / "tracks.csv").exists(), (rc, err)
        rc, out, err, p = cli(capsys, "record", bag, "--duration", "0.1")
        assert not p, (name, p)
        if mutate is not None:
            assert rc == 2 and "exists already" in err
