"""One corrupt MCAP chunk loses only its own messages (issue 28 item 5): play skips it with one
line and plays the rest, `bag info --check` finds it, `bag reindex` drops it from the file."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import pytest
import yaml
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from vizzy_runtime import cli, dds, msgs
from vizzy_runtime.bag import BagReader, BagWriter, Player, bag_check, reindex_bag

T0 = 1_700_000_000_000_000_000
CHUNKS, PER_CHUNK = 6, 40
String = msgs.get_message('std_msgs/msg/String')
Sample = tuple[str, bytes, int]  # topic, cdr, log time


def write_bag(bag: Path, compression: str) -> list[list[Sample]]:
    """CHUNKS chunks of PER_CHUNK messages on two topics; the messages of each chunk."""
    chunks: list[list[Sample]] = []
    with BagWriter(bag, compression=compression, flush_interval=1e9,
                   custom_data={'robot': 'vizzy'}) as writer:
        writer.add_topic('/a', 'std_msgs/msg/String')
        writer.add_topic('/b', 'std_msgs/msg/String')
        n = 0
        for _ in range(CHUNKS):
            chunk = []
            for _ in range(PER_CHUNK):
                data = bytes(msgs.serialize(String(data=f'message {n} ' + 'xyz' * (n % 17)),
                                            'std_msgs/msg/String'))
                sample = ('/a' if n % 2 else '/b', data, T0 + n * 1_000_000)
                writer.write(*sample)
                chunk.append(sample)
                n += 1
            writer.flush()  # one chunk
            chunks.append(chunk)
    return chunks


def chunk_indexes(file: Path) -> list[Any]:
    with open(file, 'rb') as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)


def flip_byte(file: Path, number: int) -> None:
    """Invert one byte in the middle of chunk `number`'s (1-based) stored data: compressed data,
    or with no compression the CRC-covered records themselves."""
    ci = chunk_indexes(file)[number - 1]
    data_start = ci.chunk_start_offset + 9 + 8 + 8 + 8 + 4 + 4 + len(ci.compression) + 8
    raw = bytearray(file.read_bytes())
    raw[data_start + ci.compressed_size // 2] ^= 0xFF
    file.write_bytes(bytes(raw))


def read_all(bag: Path) -> tuple[list[Sample], BagReader]:
    reader = BagReader(bag)
    return [(m.topic, m.data, m.log_time_ns) for m in reader.messages()], reader


def warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


class CountingWriter:
    """Stands in for dds.RawWriter: counts what Player writes, no network."""

    written: dict[str, list[bytes]] = {}

    def __init__(self, topic: str, _typename: str, _qos: object) -> None:
        self.topic = topic
        CountingWriter.written[topic] = []

    def write(self, data: bytes) -> None:
        CountingWriter.written[self.topic].append(bytes(data))

    def matched_count(self) -> int:
        return 1


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
@pytest.mark.parametrize('bad', [1, 4])  # chunk 1 also holds the schema and channel records
def test_play_skips_a_corrupt_chunk_and_plays_the_rest(
        tmp_path: Path, compression: str, bad: int, caplog: pytest.LogCaptureFixture,
        monkeypatch: pytest.MonkeyPatch) -> None:
    bag = tmp_path / 'bag'
    chunks = write_bag(bag, compression)
    flip_byte(bag / 'bag_0.mcap', bad)
    good = [m for i, chunk in enumerate(chunks, 1) if i != bad for m in chunk]

    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        got, reader = read_all(bag)
    assert got == good  # before the fix: only the chunks before the bad one, then BagError
    [line] = warnings(caplog)
    assert f'skipped corrupt chunk bag_0.mcap chunk {bad} of {CHUNKS}' in line
    assert f'{PER_CHUNK} messages' in line
    [corrupt] = reader.corrupt_chunks
    assert (corrupt.number, corrupt.messages) == (bad, PER_CHUNK)

    # Player.run() itself, its DDS writers replaced by counters; looping twice says it once
    monkeypatch.setattr(dds, 'RawWriter', CountingWriter)
    monkeypatch.setattr(dds, 'delete', lambda _w: None)
    caplog.clear()
    player = Player(bag, rate=1e9)
    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        counts = player.run(handle_signals=False)
        player.run(handle_signals=False)
    assert counts == {'/a': len(good) // 2, '/b': len(good) // 2}
    assert CountingWriter.written['/a'] == [d for t, d, _ in good if t == '/a']
    assert len(warnings(caplog)) == 1 and len(player.corrupt_chunks) == 1


@pytest.mark.parametrize('compression', ['zstd', 'none'])
def test_info_check_finds_and_reindex_drops_corrupt_chunks(
        tmp_path: Path, compression: str, capsys: pytest.CaptureFixture[str],
        caplog: pytest.LogCaptureFixture) -> None:
    bag = tmp_path / 'bag'
    chunks = write_bag(bag, compression)
    file = bag / 'bag_0.mcap'
    flip_byte(file, 2)
    flip_byte(file, 5)
    good = [m for i, chunk in enumerate(chunks, 1) if i not in (2, 5) for m in chunk]

    assert cli.main(['bag', 'info', '--check', str(bag)]) == 1  # before: no --check at all
    out = capsys.readouterr().out
    assert 'Messages:          240' in out  # the summary still says what was recorded
    assert (f'Check:             DAMAGED: 2 of {CHUNKS} chunks corrupt, {2 * PER_CHUNK} messages '
            f'unreadable, {len(good)} readable') in out
    assert f'bag_0.mcap chunk 2 of {CHUNKS}' in out and f'bag_0.mcap chunk 5 of {CHUNKS}' in out

    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        assert cli.main(['bag', 'reindex', str(bag)]) == 0  # before: silent, bag unchanged
    out = capsys.readouterr().out
    assert out.strip() == (f'{bag}: rebuilt metadata.yaml: {len(good)} messages on 2 topics in '
                           f'1 file(s); dropped 2 corrupt chunk(s) with {2 * PER_CHUNK} messages')
    [line] = warnings(caplog)
    assert 'dropped 2 corrupt chunks' in line and f'kept {len(good)} messages' in line

    caplog.clear()
    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        got, reader = read_all(bag)
    assert got == good and not reader.corrupt_chunks and not warnings(caplog)
    assert len(chunk_indexes(file)) == CHUNKS - 2  # the good chunks keep their boundaries
    assert bag_check(bag).ok
    assert cli.main(['bag', 'info', '--check', str(bag)]) == 0
    assert f'Check:             OK: {CHUNKS - 2} chunks, {len(good)} messages' in \
        capsys.readouterr().out

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['message_count'] == len(good) and meta['custom_data'] == {'robot': 'vizzy'}
    assert {t['topic_metadata']['name']: t['message_count']
            for t in meta['topics_with_message_count']} == {'/a': 80, '/b': 80}
    with open(file, 'rb') as f:
        reader_ = make_reader(f, validate_crcs=True)
        assert reader_.get_header().profile == 'ros2'
        [record] = [m for m in reader_.iter_metadata() if m.name == 'rosbag2']
    inner = yaml.safe_load(record.metadata['serialized_metadata'])
    assert inner['message_count'] == len(good) and inner['custom_data'] == {'robot': 'vizzy'}
    with AnyReader([bag], default_typestore=msgs.registry().store) as theirs:
        assert [(c.topic, bytes(raw), t) for c, t, raw in theirs.messages()] == good

    assert reindex_bag(bag).dropped == []  # a healthy bag is left as it is


def test_killed_recording_with_a_corrupt_chunk(tmp_path: Path,
                                               caplog: pytest.LogCaptureFixture) -> None:
    """An unfinished file is scanned record by record: the corrupt chunk is skipped (counted
    from the message indexes that follow it), the chunks after it are recovered."""
    bag = tmp_path / 'killed'
    chunks = write_bag(bag, 'zstd')
    file = bag / 'killed_0.mcap'
    indexes = chunk_indexes(file)
    flip_byte(file, 3)
    with open(file, 'r+b') as f:  # as if killed after the last chunk: no summary, no footer
        f.truncate(indexes[-1].chunk_start_offset + indexes[-1].chunk_length
                   + indexes[-1].message_index_length)
    (bag / 'metadata.yaml').unlink()
    good = [m for i, chunk in enumerate(chunks, 1) if i != 3 for m in chunk]

    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        got, _ = read_all(bag)
    assert got == good
    [line] = warnings(caplog)
    assert f'recovered {len(good)} messages from {CHUNKS - 1} complete chunks' in line
    assert f'dropped 1 corrupt chunk with {PER_CHUNK} messages (chunk 3 (byte' in line
    assert bag_check(bag).ok


def test_damaged_summary_reads_the_data_section(tmp_path: Path,
                                                caplog: pytest.LogCaptureFixture) -> None:
    bag = tmp_path / 'bag'
    chunks = write_bag(bag, 'zstd')
    file = bag / 'bag_0.mcap'
    with open(file, 'rb') as f:
        reader = make_reader(f)
        reader.get_summary()
        f.seek(-(20 + 8 + 9), 2)
        footer = f.read(9 + 20)
    summary_start = int.from_bytes(footer[9:17], 'little')
    raw = bytearray(file.read_bytes())
    raw[summary_start:summary_start + 9] = b'\xff' * 9  # the first summary record's header
    file.write_bytes(bytes(raw))
    everything = [m for chunk in chunks for m in chunk]
    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        got, _ = read_all(bag)
    assert got == everything
    assert 'damaged summary' in warnings(caplog)[0]
    check = bag_check(bag)
    assert not check.ok and 'damaged summary' in check.files[0].problem
    assert reindex_bag(bag).metadata.message_count == len(everything)
    assert bag_check(bag).ok
