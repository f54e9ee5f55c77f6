"""The motion capture the trainer compares its punches with, and starts searches from: the CMU 143/23 file
(package data, punch_trainer/data), its BVH reading (`bvh`), its four punches (`punches`) and their retargeting
onto the character's joints (`prior`). The lowest layer: it needs none of the others."""
