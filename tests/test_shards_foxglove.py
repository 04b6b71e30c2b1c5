"""Foxglove's 3D panel shows only the current scene's boxes (#22 defect 5).

The scene updates are read with the official `mcap` reader and decoded from the schema stored in the
file (as Foxglove does), then replayed with the 3D panel's rules: deletions first (type ALL removes
entities with a timestamp earlier than the deletion's), then entities added or replaced by id, and an
entity with a non-zero lifetime expires lifetime after its timestamp.
"""

from __future__ import annotations

import pytest

from refspatial_gen.shards import ShardWriter
from refspatial_gen.sources.toy_samples import make_samples


def _decoded_updates(path):
    """[(topic, log_time, SceneUpdate message)] decoded from the FileDescriptorSet in the file."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    from mcap.reader import make_reader

    out, classes = [], {}
    with open(path, "rb") as f:
        for schema, channel, msg in make_reader(f, validate_crcs=True).iter_messages(log_time_order=True):
            if schema.name != "foxglove.SceneUpdate":
                continue
            if schema.id not in classes:
                pool = descriptor_pool.DescriptorPool()
                for fd in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
                    pool.Add(fd)
                classes[schema.id] = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
            out.append((channel.topic, msg.log_time, classes[schema.id].FromString(msg.data)))
    return out


def _ns(ts) -> int:
    return ts.seconds * 1_000_000_000 + ts.nanos


def _panel_replay(updates, probe_offsets=(0, 500_000_000)):
    """{(topic, time): visible entity ids} after each update, at the update time and half a sample later."""
    shown: dict[str, dict[str, object]] = {}
    seen = {}
    for topic, t, su in updates:
        ents = shown.setdefault(topic, {})
        for d in su.deletions:
            if d.type == 1:  # ALL
                for k in [k for k, e in ents.items() if _ns(e.timestamp) < _ns(d.timestamp)]:
                    del ents[k]
            else:
                ents.pop(d.id, None)
        for e in su.entities:
            ents[e.id] = e
        for off in probe_offsets:
            now = t + off
            alive = {k for k, e in ents.items() if _ns(e.lifetime) == 0 or _ns(e.timestamp) + _ns(e.lifetime) > now}
            seen[(topic, now)] = alive
    return seen


@pytest.fixture(scope="module")
def shard(tmp_path_factory):
    samples = make_samples(8, seed=17, width=64, height=48, n_qa=1, views=2)
    p = tmp_path_factory.mktemp("fox") / "shard.mcap"
    w = ShardWriter(p)
    for s in samples:
        w.write(s)
    w.finish()
    return p, samples


def test_3d_panel_shows_only_the_current_scene(shard):
    path, samples = shard
    updates = _decoded_updates(path)
    assert len(updates) == 2 * len(samples)
    counts = {len(s.frames[0].objects) for s in samples}
    assert len(counts) > 1  # scenes with different numbers of boxes: stale ones would show
    visible = _panel_replay(updates)
    stale = 0
    for topic, t, su in updates:
        current = {e.id for e in su.entities}
        assert len(current) == len(su.entities)  # ids unique within the scene
        for off in (0, 500_000_000):
            stale += visible[(topic, t + off)] != current
    assert stale == 0


def test_entity_ids_are_per_scene_and_expire(shard):
    path, samples = shard
    updates = _decoded_updates(path)
    ids_by_scene = [{e.id for e in su.entities} for topic, _, su in updates if topic == "/cam0/boxes"]
    for a, b in zip(ids_by_scene, ids_by_scene[1:]):
        assert not a & b  # no id reused by the next scene
    for (topic, t, su), s in zip([u for u in updates if u[0] == "/cam0/boxes"], samples):
        assert all(e.id.startswith(s.sample_id + "/") for e in su.entities)
        assert all(_ns(e.lifetime) == 1_000_000_000 and _ns(e.timestamp) == t for e in su.entities)
        assert [(d.type, _ns(d.timestamp)) for d in su.deletions] == [(1, t)]
