"""The items a ShardStream yields: one sample, or one QA pair, with pixels decoded only on demand.

Why lazy: dataloader workers hand items to a transform that decides what to decode; keeping the encoded
message bytes until `.rgb()` / `.depth()` costs nothing for the parts a trainer never looks at.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from refspatial_gen.shards.format import RawSample


@dataclass
class StreamSample:
    """One sample from the stream; pixels are decoded on first use."""

    raw: RawSample
    shard: str
    slot: int = 0
    index: int = 0  # position within the slot's output this epoch
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def position(self) -> tuple[int, int]:
        return self.slot, self.index

    @property
    def header(self) -> dict:
        if "header" not in self._cache:
            self._cache["header"] = self.raw.header
        return self._cache["header"]

    @property
    def sample_id(self) -> str:
        return self.header["sample_id"]

    @property
    def qa(self) -> list[dict]:
        if "qa" not in self._cache:
            self._cache["qa"] = self.raw.qa_json()
        return self._cache["qa"]

    def frame_meta(self, view: int = 0) -> dict:
        return self.raw.frame_meta(view)

    def image_bytes(self, view: int = 0) -> tuple[bytes, str]:
        return self.raw.image_bytes(view)

    def rgb(self, view: int = 0):
        return self.raw.rgb(view)

    def depth(self, view: int = 0):
        return self.raw.depth(view)

    def decode(self):
        """The full core.model.Sample."""
        return self.raw.decode()


@dataclass
class StreamQA(StreamSample):
    """One QA pair with lazy access to the images of the sample it belongs to."""

    qa_index: int = 0

    @property
    def pair(self) -> dict:
        return self.qa[self.qa_index]

    @property
    def qa_id(self) -> str:
        return self.pair["qa_id"]
