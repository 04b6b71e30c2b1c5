"""Categories whose lifted position cannot rest on their mask's bottom edge (geometric depth, photos)."""

from __future__ import annotations

# categories whose mask's bottom edge is not a floor contact: a sink is set in a counter or a vanity (the basin's
# bottom edge floats at counter height), an umbrella, a handbag, a backpack or a tie is held or worn. They are
# placed on the ground all the same when nothing annotated lies under them (a held umbrella 20 m away, COCO
# 515289; a counter sink 10 m away and 0.2 m tall, 368402; a vanity sink "farther" than the toilet, 111076),
# so no 3D position claim may rest on them (sources/image/contact.py, qa/faint_photo.py)
OFF_GROUND = frozenset({"sink", "umbrella", "handbag", "backpack", "tie"})
