"""Reading shards: raw message groups, full Samples, or metadata only.

Why a sequential record reader rather than the indexed one: training reads whole shards front to
back, and the sequential reader needs no footer, so the same code serves finished shards (which must
end with a footer, else ShardError) and salvage of unfinished ones (`require_footer=False`).
Every failure is a ShardError naming the file, never a library traceback.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterator

from refspatial_gen.core.model import Sample
from refspatial_gen.shards.format import RawSample, is_complete


class ShardError(ValueError):
    """A shard that cannot be read as it should: `path` and a plain-language `reason`."""

    def __init__(self, path: Path | str, reason: str) -> None:
        self.path, self.reason = str(path), reason
        super().__init__(f"{self.path}: {reason}")


def iter_raw(path: Path | str, *, require_footer: bool = True, validate_crcs: bool = True,
             keep_topic: Callable[[str], bool] | None = None) -> Iterator[RawSample]:
    """Yield each sample's messages grouped by sequence number, in file order.

    With `require_footer=False` (salvage), stops quietly at the first damaged record and yields only
    complete samples; otherwise a damaged or truncated file raises ShardError after the last good sample.
    `keep_topic` limits which messages' bytes are kept (others are counted for completeness only).
    """
    from mcap.exceptions import McapError
    from mcap.records import Channel, Footer, Message
    from mcap.stream_reader import StreamReader

    path = Path(path)
    try:
        f = open(path, "rb")
    except OSError as e:
        raise ShardError(path, f"cannot open: {e.strerror or e}") from None
    with f:
        reader = StreamReader(f, validate_crcs=validate_crcs, record_size_limit=1 << 31)
        channels: dict[int, str] = {}
        cur_seq: int | None = None
        cur: dict[str, bytes] = {}
        footer = False
        it = reader.records
        while True:
            try:
                rec = next(it)
            except StopIteration:
                break
            except (McapError, ValueError, EOFError, OSError, struct_error(), MemoryError, IndexError) as e:
                if not require_footer:
                    break
                raise ShardError(path, _explain(e)) from None
            if isinstance(rec, Channel):
                channels[rec.id] = rec.topic
            elif isinstance(rec, Message):
                topic = channels.get(rec.channel_id)
                if topic is None:
                    if not require_footer:
                        break
                    raise ShardError(path, f"message on unknown channel {rec.channel_id}")
                if rec.sequence != cur_seq:
                    if cur_seq is not None and (require_footer or is_complete(cur)):
                        yield _finish_group(path, cur_seq, cur)
                    cur_seq, cur = rec.sequence, {}
                if keep_topic is None or topic == "/sample" or keep_topic(topic):
                    cur[topic] = rec.data
                else:
                    cur[topic] = b""  # counted for completeness, not kept
            elif isinstance(rec, Footer):
                footer = True
        if cur_seq is not None:
            if footer or is_complete(cur):
                yield _finish_group(path, cur_seq, cur)
        if require_footer and not footer:
            raise ShardError(path, "truncated: the file ends before the MCAP footer (unfinished write?); "
                                   "try `refspatial-gen shards salvage`")


def _finish_group(path: Path, seq: int, msgs: dict[str, bytes]) -> RawSample:
    if not is_complete(msgs):
        raise ShardError(path, f"sample with sequence {seq} is incomplete ({len(msgs)} messages)")
    return RawSample(seq, msgs)


def struct_error():
    import struct

    return struct.error


def _explain(e: BaseException) -> str:
    name = type(e).__name__
    if name == "InvalidMagic":
        return "not an MCAP file (bad magic bytes)"
    if name == "EndOfFile" or isinstance(e, EOFError):
        return "truncated: the file ends in the middle of a record (unfinished write?)"
    if name == "CRCValidationError":
        return f"corrupt: a chunk's CRC does not match ({e})"
    if name == "RecordLengthLimitExceeded":
        return "corrupt: a record claims an impossible length (random bytes or damaged file)"
    return f"unreadable ({name}: {e})"


def read_samples(path: Path | str) -> Iterator[Sample]:
    """Every Sample of a finished shard, fully decoded (RGB, depth, masks, graphs, QA)."""
    for raw in iter_raw(path):
        try:
            yield raw.decode()
        except (ValueError, KeyError, TypeError) as e:
            raise ShardError(path, f"sample with sequence {raw.seq} does not decode: {e}") from None


def read_sample_meta(path: Path | str) -> Iterator[dict]:
    """Per sample: {seq, sample_id, unit_key, meta, frames (Frame.meta_json), graphs, qa} — no pixels decoded."""
    for raw in iter_raw(path, keep_topic=_meta_topic):
        yield raw.meta()


def _meta_topic(topic: str) -> bool:
    return topic in ("/graphs", "/qa") or topic.endswith("/frame")
