"""The ``quality=`` presets of :func:`render` and :func:`render_volume`: one word for the knobs
docs/speed_accuracy.md measures, each preset a point on their Pareto fronts there
(bench/tradeoffs.py measures the presets themselves too)."""

from __future__ import annotations

QUALITIES = ("exact", "balanced", "fast")

# render: the ray/triangle test. Watertight lets no ray through a closed mesh at the speed of
# Moller-Trumbore on the CPU; Moller-Trumbore is the one test of both backends.
_TRIANGLE_TEST = {"exact": "watertight", "balanced": "moller-trumbore", "fast": "moller-trumbore"}

# render_volume: (sample distance in units of its default, half the smallest spacing; image
# sample distance; early-termination opacity). On headsq (docs/speed_accuracy.md) "exact" draws
# about 80 dB PSNR against the fine reference at 3x the time of "balanced" (the defaults, 67 dB);
# "fast" casts 4x fewer rays with half the samples each (44 dB, 4x faster).
_VOLUME = {"exact": (0.25, 1.0, 1.0), "balanced": (1.0, 1.0, 0.99), "fast": (2.0, 2.0, 0.95)}


def _checked(quality: str) -> str:
    if quality not in QUALITIES:
        raise ValueError(f"quality must be one of {', '.join(map(repr, QUALITIES))}, got {quality!r}")
    return quality


def triangle_test(quality: str | None, given: str) -> str:
    """The triangle test of ``quality`` (None: ``given``). ValueError when both are chosen."""
    if quality is None:
        return given
    if given != "moller-trumbore":
        raise ValueError(f"pass quality= or triangle_test=, not both (got quality={quality!r}, "
                         f"triangle_test={given!r})")
    return _TRIANGLE_TEST[_checked(quality)]


def volume(quality: str | None, sample_distance, image_sample_distance, early_termination):
    """(factor on the default sample distance, image_sample_distance, early_termination) of
    ``quality``; None: (1, the given two). ValueError when a knob is chosen along with quality."""
    if quality is None:
        return 1.0, image_sample_distance, early_termination
    _checked(quality)
    given = [name for name, value, default in (("sample_distance", sample_distance, None),
                                               ("image_sample_distance", image_sample_distance, 1.0),
                                               ("early_termination", early_termination, 0.99)) if value != default]
    if given:
        raise ValueError(f"pass quality= or {', '.join(given)}=, not both (quality={quality!r} sets them)")
    return _VOLUME[quality]
