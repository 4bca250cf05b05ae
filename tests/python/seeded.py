"""Seeded random queries shared by the test files: points in and around a data set's bounding
box, and segment starts with their directions."""

import numpy as np


def random_points(ds, n, seed, grow=0.05):
    """``n`` points uniform in ``ds``'s bounding box grown by ``grow`` of its extent on every side."""
    b = np.array(ds.GetBounds()).reshape(3, 2)
    ext = b[:, 1] - b[:, 0]
    return b[:, 0] - grow * ext + np.random.default_rng(seed).random((n, 3)) * ext * (1 + 2 * grow)


def start_and_direction(rng, b):
    """A point uniform in the box ``b`` (rows: axes; columns: min, max) and an unnormalised
    direction with normal components, drawn from ``rng`` in that order."""
    p1 = b[:, 0] + rng.random(3) * (b[:, 1] - b[:, 0])
    return p1, rng.normal(size=3)
