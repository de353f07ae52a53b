"""How range noise and beam smoothing bias measured roughness (TLS instrument-bias paper).

    python examples/05_scanner_bias.py

Simulates the paper's target A (36 hemispheres of radius 19 mm) with 1.6 mm range
noise and a 4 mm effective beam radius.
"""

from __future__ import annotations

import rough_viewer as rv

p = rv.predict_bias(noise_sigma_m=0.0016, effective_radius_m=0.004, trials=1, seed=0)
print(f"expected {p.expected_m * 1e3:.3f} mm")
print(f"with noise {p.noise_only_m * 1e3:.3f} mm ({p.noise_effect_pct:+.1f} %)")
print(f"with beam smoothing {p.smoothing_only_m * 1e3:.3f} mm ({p.smoothing_effect_pct:+.1f} %)")
print(f"measured {p.measured_m * 1e3:.3f} mm ({p.total_effect_pct:+.1f} %)")
