"""ShardWriter: Samples -> MCAP shard files, atomically, byte-identically, rolling over at a size limit.

Why the care: runs must give byte-identical shards for identical inputs (parallel or not), and a crash
must never leave a file that looks finished. So: message times come from the sample sequence number,
the mcap library writes no clock or host data (checked in tests), and each part is written as
`<name>.partial` and renamed only after `finish()` wrote its footer.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path

from refspatial_gen.core.fsutil import sha256_file  # re-exported: shards.sha256_file
from refspatial_gen.core.model import Sample
from refspatial_gen.shards.format import (
    JSON_SCHEMA,
    NS_PER_SAMPLE,
    PROFILE,
    encode_sample,
    json_schema_data,
    protobuf_schema_data,
    topic_schema,
)

PARTIAL_SUFFIX = ".partial"
CHUNK_SIZE = 4 * 1024 * 1024


@dataclass
class ShardInfo:
    """What index.json records about one shard file."""

    name: str
    samples: int
    qa_pairs: int
    bytes: int
    sha256: str

    def to_dict(self) -> dict:
        return asdict(self)

    def keys(self):  # dict(info) works
        return self.to_dict().keys()

    def __getitem__(self, k: str):
        return self.to_dict()[k]


def part_name(final_path: Path, part: int) -> Path:
    """shard-00003.mcap, shard-00003-01.mcap, shard-00003-02.mcap, ..."""
    final_path = Path(final_path)
    if part == 0:
        return final_path
    return final_path.with_name(f"{final_path.stem}-{part:02d}{final_path.suffix}")


class _Part:
    """One open MCAP file being written under its .partial name."""

    def __init__(self, path: Path, chunk_size: int, tmp_suffix: str = PARTIAL_SUFFIX) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self.tmp = self.path.with_name(self.path.name + tmp_suffix)
        self.tmp.parent.mkdir(parents=True, exist_ok=True)
        self.f = open(self.tmp, "wb")
        self.w = Writer(self.f, chunk_size=chunk_size, compression=CompressionType.ZSTD, enable_data_crcs=True)
        self.w.start(profile=PROFILE)
        self.channels: dict[str, int] = {}
        self.schemas: dict[str, int] = {}
        self.samples = 0
        self.qa_pairs = 0
        self.pending = 0  # uncompressed bytes in the open chunk (not yet in the file)
        self.last_tell = self.f.tell()

    def channel(self, topic: str) -> int:
        cid = self.channels.get(topic)
        if cid is None:
            name, enc = topic_schema(topic)
            sid = self.schemas.get(name)
            if sid is None:
                data = json_schema_data(name) if enc == JSON_SCHEMA else protobuf_schema_data(name)
                sid = self.w.register_schema(name=name, encoding=enc, data=data)
                self.schemas[name] = sid
            cid = self.w.register_channel(
                topic=topic, message_encoding="json" if enc == JSON_SCHEMA else "protobuf", schema_id=sid
            )
            self.channels[topic] = cid
        return cid

    def size_estimate(self) -> int:
        """Bytes on disk plus the open chunk uncompressed: never less than what the file will hold."""
        return self.f.tell() + self.pending

    def add(self, messages: list[tuple[str, bytes]], seq: int, qa_pairs: int) -> None:
        t = (seq + 1) * NS_PER_SAMPLE
        for topic, data in messages:
            self.w.add_message(channel_id=self.channel(topic), log_time=t, publish_time=t, data=data, sequence=seq)
            tell = self.f.tell()
            if tell != self.last_tell:  # the chunk holding this message was just written out
                self.last_tell, self.pending = tell, 0
            else:
                self.pending += len(data) + len(topic) + 32
        self.samples += 1
        self.qa_pairs += qa_pairs

    def close(self) -> ShardInfo:
        self.w.finish()
        self.f.flush()
        os.fsync(self.f.fileno())
        self.f.close()
        os.replace(self.tmp, self.path)
        return ShardInfo(self.path.name, self.samples, self.qa_pairs, self.path.stat().st_size, sha256_file(self.path))

    def abort(self) -> None:
        if not self.f.closed:
            self.f.close()


class ShardWriter:
    """Write Samples to `final_path` (and `<stem>-01<suffix>`, ... when `max_bytes` is reached).

    Usage: `w = ShardWriter(path); w.write(sample) ...; infos = w.finish()`. Nothing exists under the
    final name(s) until `finish()` returns. A part holds at least one sample, so a single sample larger
    than `max_bytes` still gets written (alone in its part).
    """

    def __init__(
        self,
        final_path: Path,
        *,
        max_bytes: int | None = None,
        image_format: str = "jpeg",
        chunk_size: int = CHUNK_SIZE,
    ) -> None:
        if image_format not in ("jpeg", "png"):
            raise ValueError(f"image_format must be 'jpeg' or 'png', got {image_format!r}")
        self.final_path = Path(final_path)
        self.max_bytes = max_bytes
        self.image_format = image_format
        self.chunk_size = chunk_size if max_bytes is None else max(64 * 1024, min(chunk_size, max_bytes // 4))
        self.seq = 0
        self._parts_done: list[ShardInfo] = []
        self._part: _Part | None = None
        self._finished = False

    def write(self, sample: Sample) -> None:
        if self._finished:
            raise RuntimeError(f"{self.final_path}: write() after finish()")
        msgs = encode_sample(sample, self.seq, self.image_format)
        size = sum(len(d) + len(t) + 32 for t, d in msgs)
        if (
            self._part is not None
            and self.max_bytes is not None
            and self._part.samples > 0
            and self._part.size_estimate() + size > self.max_bytes
        ):
            self._parts_done.append(self._part.close())
            self._part = None
        if self._part is None:
            self._part = _Part(part_name(self.final_path, len(self._parts_done)), self.chunk_size)
        self._part.add(msgs, self.seq, len(sample.qa))
        self.seq += 1

    def finish(self) -> list[ShardInfo]:
        """Close the open part; returns one ShardInfo per part file (an empty writer writes one empty shard)."""
        if self._finished:
            return list(self._parts_done)
        if self._part is None and not self._parts_done:
            self._part = _Part(self.final_path, self.chunk_size)
        if self._part is not None:
            self._parts_done.append(self._part.close())
            self._part = None
        self._finished = True
        return list(self._parts_done)

    def abort(self) -> None:
        """Close the open part without finishing it (it stays as .partial, salvageable)."""
        if self._part is not None:
            self._part.abort()
            self._part = None
        self._finished = True

    def __enter__(self) -> ShardWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.finish()
        else:
            self.abort()
