"""The report's joint sets carry the rock-mass figures (Jv, block size index, RQD
estimate with its formula and limits) and every set's roughness (issue 30 items 3
and 4), in the page and in the JSON, in the display unit."""

from __future__ import annotations

import html

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.report import build_report, report_html, report_json
from rough_viewer.structure.sets import SET_COLUMNS, joint_sets
from rough_viewer.synthetic.joints import RockMassSetSpec, RockMassSpec, generate_rock_mass

G = 0.25


@pytest.fixture(scope="module")
def rock():
    """A 2 m block of two sets of three joints 0.6 m apart, 2 cm point spacing, one
    set corrugated along its dip (4 mm, 10 cm), 0.3 mm noise (59 k points)."""
    spec = RockMassSpec(size_m=2.0, point_spacing_m=0.02, noise_m=0.0003, sets=(
        RockMassSetSpec(40.0, 120.0, joints=3, spacing_m=0.6, corrugation_m=0.004,
                        corrugation_wavelength_m=0.1),
        RockMassSetSpec(70.0, 250.0, joints=3, spacing_m=0.6)))
    return generate_rock_mass(spec).cloud


def test_report_states_the_rock_mass_figures_and_set_roughness(rock):
    ref = joint_sets(grid_roughness(rock, G, axis="z"), rock)
    assert ref.n_sets == 2 and ref.figures.sets_counted == 2
    f, r = ref.figures, ref.roughness
    for unit, per in (("m", 1.0), ("mm", 1e-3)):
        rep = build_report(rock, [G], axis="z", unit=unit)
        page = html.unescape(report_html(rep))
        section = page.split('<section id="grid-0_25"')[1].split("</section>")[0]
        u = "m" if unit == "m" else "mm"
        in_m = "" if unit == "m" else f"{f.jv:.3g} per m³; "
        assert f"Jv = {f.jv * per:.3g} joints per {u}³ ({in_m}the sum over the 2 sets" in section
        assert f"block size index Ib = {f.block_size_index / per:.3g} {u}" in section
        assert f"RQD estimate {f.rqd_estimate:.0f} % from RQD = 110 − 2.5 Jv" in section
        assert "for Jv from 4 to 44 (100 below, 0 above), not a measured RQD" in section
        table = section.split('data-table="set_roughness">')[1].split("</table>")[0]
        rows = [[c.split("</td>")[0] for c in row.split("<td>")[1:]]
                for row in table.split("<tr>")[2:]]
        assert len(rows) == 2
        assert "JRC estimate dip" in table and "θ*max/(C+1) strike (°)" in table
        for k, row in enumerate(rows):
            assert row[2] == f"{ref.n_joints_per_set[k]:,}"
            assert row[3] == f"{ref.spacing_mean[k] / per:.3g}"
            assert row[5] == f"{r.odr_mean[k] / 1e-3:.3g}"  # roughness in mm either way
            assert row[8] == f"{r.jrc_estimate_dip[k]:.1f}"
            assert row[10] == f"{r.theta_max_c1_dip[k]:.1f}"
            assert row[13] == f"{r.delta_t_strike[k]:.1f}"
        rough = int(np.nanargmax(r.delta_t_dip))
        assert r.delta_t_dip[rough] > 3 * r.delta_t_strike[rough]  # the corrugated set
        assert "JRC estimates (Tse and Cruden 1979) hold for profiles sampled" in section
        data = report_json(rep)["grids"][0]["sets"]
        assert data["columns"] == list(SET_COLUMNS)
        assert data["jv"] == pytest.approx(f.jv * per)
        assert data["jv_per_m3"] == pytest.approx(f.jv)
        assert data["block_size_index"] == pytest.approx(f.block_size_index / per)
        assert data["rqd_estimate"] == pytest.approx(f.rqd_estimate)
        assert "110 - 2.5 Jv" in data["rqd_estimate_formula"]
        i = SET_COLUMNS.index("odr_mean")
        assert [row[i] for row in data["rows"]] == pytest.approx(r.odr_mean / per)
        i = SET_COLUMNS.index("jrc_estimate_strike")
        assert [row[i] for row in data["rows"]] == pytest.approx(r.jrc_estimate_strike)
