"""Seeded random scenes (`nlos-cl reproduce draws`, the bench's crossing stream, the mitransient
scripts): `families.draw(family, index, master_seed)` is a pure function that returns plain
data, `crossings` the geometry of two crossing paths, and `scenes` turns a draw into a
physics.Scene, its clean frame and the frame the estimators see. The ranges every draw is taken
from are draws.yaml (package data)."""
