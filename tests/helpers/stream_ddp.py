"""Run under `torchrun --nproc_per_node 2` (CPU, gloo): each rank streams with 2 DataLoader workers and the
default collate; checks exactly-once per epoch across ranks, set_epoch, and a mid-epoch resume.

argv: SHARD_DIR OUT_JSON. Rank 0 writes {"epochs": [...], "resume_ok": bool, "lens": [...]} to OUT_JSON.
"""

from __future__ import annotations

import json
import sys


def main() -> None:
    import torch.distributed as dist
    from torch.utils.data import DataLoader

    from helpers.stream_items import ids_of, item_id
    from refspatial_gen.stream import ShardStream

    shard_dir, out = sys.argv[1], sys.argv[2]
    dist.init_process_group("gloo")
    rank, world = dist.get_rank(), dist.get_world_size()
    make = lambda: ShardStream.torch(shard_dir, seed=7, buffer_size=4, num_workers=2, transform=item_id)  # noqa: E731
    ds = make()
    loader = DataLoader(ds, batch_size=2, num_workers=2, persistent_workers=True)
    epochs = []
    for epoch in range(2):
        ds.set_epoch(epoch)
        mine = [i for b in loader for i in ids_of(b)]
        allv = [None] * world
        dist.all_gather_object(allv, mine)
        epochs.append([sorted(x for part in allv for x in part), [x for part in allv for x in part]])
    # epoch 2: stop after two batches, checkpoint, resume in a fresh dataset and loader
    ds.set_epoch(2)
    it = iter(DataLoader(ds, batch_size=2, num_workers=2))
    head = []
    for _ in range(2):
        b = next(it)
        ds.record(b)
        head += ids_of(b)
    del it
    state = ds.state_dict()
    ds2 = make()
    ds2.load_state_dict(state)
    rest = [i for b in DataLoader(ds2, batch_size=2, num_workers=2) for i in ids_of(b)]
    got = [None] * world
    dist.all_gather_object(got, head + rest)
    lens = [None] * world
    dist.all_gather_object(lens, [len(ds), len(head + rest)])
    if rank == 0:
        flat = [x for part in got for x in part]
        with open(out, "w") as f:
            json.dump({"epochs": epochs, "resumed": sorted(flat), "resumed_n": len(flat), "lens": lens,
                       "state_world": state["world_size"]}, f)
    dist.destroy_process_group()


if __name__ == "__main__":
    main()
