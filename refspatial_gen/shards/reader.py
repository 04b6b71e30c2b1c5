"""Reading shards: raw message groups, full Samples, or metadata only.

Why a sequential record reader rather than the indexed one: training reads whole shards front to
back, and the sequential reader needs no footer, so the same code serves finished shards (which must
end with a footer, else ShardError) and salvage of unfinished ones (`require_footer=False`).
Every failure is a ShardError naming the file, never a library traceback.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

from refspatial_gen.core.model import Sample
from refspatial_gen.shards.format import RawSample, is_complete


class ShardError(ValueError):
    """A shard that cannot be read as it should: `path` and a plain-language `reason`."""

    def __init__(self, path: Path | str, reason: str) -> None:
        self.path, self.reason = str(path), reason
        super().__init__(f"{self.path}: {reason}")


def iter_raw(
    path: Path | str,
    *,
    require_footer: bool = True,
    validate_crcs: bool = True,
    check_index: bool = True,
    keep_topic: Callable[[str], bool] | None = None,
) -> Iterator[RawSample]:
    """Yield each sample's messages grouped by sequence number, in file order.

    With `require_footer=False` (salvage), stops quietly at the first damaged record and yields only
    complete samples; otherwise a damaged or truncated file raises ShardError after the last good sample.
    `keep_topic` limits which messages' bytes are kept (others are counted for completeness only).
    `validate_crcs` checks every MCAP CRC (chunks before their messages are yielded; data section and
    summary at the end). `check_index` (finished shards only) first checks the file's size and sha256
    against the index.json beside it, once per process (`shards.trust`), so nothing is yielded from
    an altered shard.
    """
    from refspatial_gen.shards.mcapscan import ScanError, scan
    from refspatial_gen.shards.trust import IntegrityError, verify_against_index

    path = Path(path)
    if not path.is_file():
        raise ShardError(path, "no such file" if not path.exists() else "not a regular file")
    if check_index and require_footer:
        try:
            verify_against_index(path)
        except IntegrityError as e:
            raise ShardError(path, str(e)) from None
        except OSError as e:
            raise ShardError(path, f"cannot read: {e.strerror or e}") from None
    cur_seq: int | None = None
    cur: dict[str, bytes] = {}
    footer = False
    it = scan(path, validate_crcs=validate_crcs)
    while True:
        try:
            rec = next(it)
        except StopIteration:
            break
        except ScanError as e:
            if not require_footer and e.kind != "not_mcap":
                break
            hint = "; try `refspatial-gen shards salvage`" if e.kind == "truncated" else ""
            raise ShardError(
                path, f"{e.kind.replace('_', ' ') if e.kind != 'not_mcap' else 'invalid'}: {e}{hint}"
            ) from None
        except OSError as e:
            raise ShardError(path, f"cannot read: {e.strerror or e}") from None
        if rec is None:
            footer = True
            continue
        topic, seq, data = rec
        if seq != cur_seq:
            if cur_seq is not None and (require_footer or is_complete(cur)):
                yield _finish_group(path, cur_seq, cur)
            cur_seq, cur = seq, {}
        cur[topic] = data if keep_topic is None or topic == "/sample" or keep_topic(topic) else b""
    if cur_seq is not None and (footer or is_complete(cur)):
        yield _finish_group(path, cur_seq, cur)
    if require_footer and not footer:
        raise ShardError(
            path,
            "truncated: the file ends before the MCAP footer (unfinished write?); try `refspatial-gen shards salvage`",
        )


def _finish_group(path: Path, seq: int, msgs: dict[str, bytes]) -> RawSample:
    if not is_complete(msgs):
        raise ShardError(path, f"sample with sequence {seq} is incomplete ({len(msgs)} messages)")
    return RawSample(seq, msgs)


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
