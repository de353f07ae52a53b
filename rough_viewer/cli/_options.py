"""Parsing of option values shared by the commands (one-line errors, exit 2)."""

from __future__ import annotations

from rough_viewer.vocabulary import InputError


def parse_xyz(text: str, *, option: str) -> tuple[float, float, float]:
    """Parse ``"X,Y,Z"`` into three floats, or raise InputError naming the option."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(v == v and abs(v) != float("inf") for v in values):
        raise InputError(f"{option} expects three finite numbers X,Y,Z, got {text!r}")
    return values  # type: ignore[return-value]
