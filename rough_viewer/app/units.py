"""How the app shows lengths and roughness in the loaded cloud's unit."""

from __future__ import annotations

import math
from dataclasses import dataclass

from rough_viewer.vocabulary import (
    ROUGHNESS_UNIT,
    UNIT_LABELS,
    UNIT_METRES,
)


@dataclass(frozen=True)
class Units:
    """How lengths are shown: grid sizes and coordinates in the cloud's unit,
    roughness in :data:`rough_viewer.vocabulary.ROUGHNESS_UNIT` of it (mm for metric
    input). The app computes in metres; only what is shown or typed is converted.

    >>> u = Units("ft")
    >>> u.length(0.3048), u.label, u.rough_label
    (1.0, 'ft', 'ft')
    >>> Units("m").rough(0.002), Units("m").rough_label
    (2.0, 'mm')
    """

    unit: str = "m"
    """Unit of the cloud's coordinates (``PointCloud.source_unit``)."""

    @property
    def per(self) -> float:
        """Metres per length unit."""
        return UNIT_METRES[self.unit]

    @property
    def label(self) -> str:
        return UNIT_LABELS[self.unit]

    @property
    def rough_unit(self) -> str:
        return ROUGHNESS_UNIT[self.unit] if self.unit in ROUGHNESS_UNIT else self.unit

    @property
    def rough_per(self) -> float:
        """Metres per roughness unit."""
        return UNIT_METRES[self.rough_unit]

    @property
    def rough_label(self) -> str:
        return UNIT_LABELS[self.rough_unit]

    def length(self, metres: float) -> float:
        """A length in metres, in the cloud's unit (rounded to 9 significant digits)."""
        return float(f"{metres / self.per:.9g}")

    def rough(self, metres: float) -> float:
        """A roughness in metres, in the roughness unit."""
        return float(metres) / self.rough_per

    def rough_text(self, metres: float) -> str:
        """A roughness as shown beside others: 3 significant digits in the roughness
        unit, a metric one under 0.01 mm in µm (e_ols of a lab mesh is
        ``"0.505 µm"``, not ``"0.0005048 mm"``); a dash when it is not finite.

        >>> Units("mm").rough_text(5.048e-7), Units("m").rough_text(0.0012345)
        ('0.505 µm', '1.23 mm')
        """
        if not math.isfinite(metres):
            return "—"
        v = self.rough(metres)
        if self.rough_unit == "mm" and v != 0.0 and abs(v) < 0.01:
            return f"{1000.0 * v:.3g} µm"
        return f"{v:.3g} {self.rough_label}"

    def size_text(self, metres: float) -> str:
        """``"0.25 m"``, ``"12.5 mm"``: a grid size as shown."""
        return f"{self.length(metres):g} {self.label}"

