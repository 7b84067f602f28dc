"""Sweep: parameters, the variant grid, ranking with ties, and a real sweep of the reference design (slow)."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from lensmount.errors import InputError
from lensmount.loop.sweep import Param, Variant, rank, variants_of

ROOT = Path(__file__).resolve().parents[2]
DESIGN = ROOT / "src" / "lensmount" / "examples" / "double-gauss-360"


def test_param_parses_file_table_key_and_toml_values():
    p = Param.parse("mount.vanes.count=3,5,7")
    assert (p.file, p.keys, p.values) == ("mount", ("vanes", "count"), (3, 5, 7))
    q = Param.parse('scene.source.off_axis_deg=7.5, 9')
    assert q.values == (7.5, 9) and q.name == "scene.source.off_axis_deg"
    assert Param.parse("mount.vanes.finish=black-anodised").values == ("black-anodised",)


@pytest.mark.parametrize("bad", ["vanes.count=3", "mount.vanes.count", "mount..count=1", "mount.vanes.count=",
                                 "hood=3"])
def test_bad_param_names_the_option(bad):
    with pytest.raises(InputError) as e:
        Param.parse(bad)
    assert e.value.field == "--param"


def test_grid_is_every_combination_in_order():
    grid = variants_of((Param.parse("mount.vanes.count=3,5"), Param.parse("mount.hood.length_mm=80,120,160")))
    assert len(grid) == 6
    assert grid[0] == {"mount.vanes.count": 3, "mount.hood.length_mm": 80}
    assert grid[-1] == {"mount.vanes.count": 5, "mount.hood.length_mm": 160}


def test_variants_within_the_noise_tie_and_separated_ones_do_not():
    vs = [Variant(0, {}, 1.00, 0.01), Variant(1, {}, 1.01, 0.01), Variant(2, {}, 2.0, 0.01),
          Variant(3, {}, 2.02, 0.01), Variant(4, {}, 2.03, 0.01), Variant(5, {}, None, None)]
    rank(vs, 0.95)
    # |Δ| against z·σ√2 = 0.0277: 0.01 and 0.02 tie with the group's best, 0.03 does not; unknown ranks last.
    assert [v.rank for v in vs] == [1, 1, 2, 2, 3, 4]
    assert vs[0].tied_with == [1] and vs[2].tied_with == [3] and vs[4].tied_with == []


def test_a_bias_bound_widens_what_counts_as_a_tie():
    a, b = Variant(0, {}, 1.0, 0.001), Variant(1, {}, 1.1, 0.001)
    rank([a, b], 0.95)
    assert (a.rank, b.rank) == (1, 2)
    a.bias_bound = b.bias_bound = 0.06
    rank([a, b], 0.95)
    assert a.rank == b.rank == 1


@pytest.mark.slow
def test_sweep_of_four_reference_variants_ranks_them(tmp_path):
    """Two parameters of two values each: a grid (not one axis), every variant regenerated and simulated.
    Four, not six: each variant costs a regenerate and a run, and a third value of one parameter checks
    nothing the second does not."""
    from lensmount.loop.simulate import SimulateOptions
    from lensmount.loop.sweep import SweepOptions, sweep

    design = tmp_path / "design"
    shutil.copytree(DESIGN, design)
    scene = design / "scenes" / "case2-lambertian.toml"
    text = scene.read_text().replace("pixels = [600, 600]", "pixels = [60, 60]")
    scene.write_text(text)
    params = (Param.parse("mount.vanes.count=0,5"), Param.parse("mount.hood.length_mm=60,100"))
    base = SimulateOptions(design, scene, passes=4, photons_per_pass=20_000, workers=2, record=False)
    result = sweep(SweepOptions(design, scene, params, tmp_path / "sweep", base))
    assert len(result.variants) == 4 and result.plot.exists()
    rows = list(csv.DictReader(result.table.open()))
    assert len(rows) == 4 and all(float(r["stray_fraction"]) > 0 and float(r["std_error"]) > 0 for r in rows)
    ranks = sorted(int(r["rank"]) for r in rows)
    assert ranks[0] == 1 and ranks == sorted(ranks)
    # Every variant was really built with its own vane count.
    for v in result.variants:
        mount = (tmp_path / "sweep" / "variants" / f"{v.index:02d}" / "design" / "mount.toml").read_text()
        assert f"count = {v.values['mount.vanes.count']}" in mount


def _written(tmp_path, *params):
    from lensmount.loop.sweep import write_variant

    grid = variants_of(params)
    scene = DESIGN / "scenes" / "case2-lambertian.toml"
    return grid, [write_variant(DESIGN, scene, tmp_path / f"{k:02d}", params, v)[0] for k, v in enumerate(grid)]


def test_a_parameter_that_builds_identical_mounts_is_refused_before_any_run(tmp_path):
    """Values of a key that does not change the mount (here [hood] exclusion_deg
    under even vane placement, which only line-of-sight vanes follow) would only measure noise."""
    from lensmount.loop.sweep import SweepOptions, refuse_identical_layouts, sweep

    params = (Param.parse("mount.hood.exclusion_deg=10,12"), Param.parse("mount.hood.length_mm=80,120"))
    with pytest.raises(InputError) as e:
        refuse_identical_layouts(params, *_written(tmp_path / "a", *params))
    assert e.value.field == "--param" and "mount.hood.exclusion_deg = 10 and 12" in str(e.value)
    # The sweep itself refuses before simulating (no run folder is made).
    with pytest.raises(InputError):
        sweep(SweepOptions(DESIGN, DESIGN / "scenes" / "case2-lambertian.toml", params[:1], tmp_path / "s"))
    assert not list((tmp_path / "s").glob("variants/*/run"))
    # A key that does change the mount passes, also under line-of-sight placement (where, on this
    # lens, exclusion_deg 6 to 30 places the same 12 hood vanes: refused there too).
    refuse_identical_layouts(params[1:], *_written(tmp_path / "b", params[1]))
    los = (Param.parse('mount.vanes.placement="line-of-sight"'), Param.parse("mount.hood.length_mm=80,120"))
    grid, designs = _written(tmp_path / "c", *los)
    for d in designs:  # the example's own count would be an error under line-of-sight
        mount = d / "mount.toml"
        mount.write_text("\n".join(line for line in mount.read_text().splitlines() if not line.startswith("count")))
    refuse_identical_layouts(los, grid, designs)


def test_the_plot_is_honest_about_scale_ticks_and_missing_bars():
    """The sweep plot reads right: integer ticks for a count (no 1.2 vanes), no offset label over the
    title, a 0.002 % difference not drawn as a steep drop, and missing error bars said when the axis
    says ±2σ."""
    import matplotlib.pyplot as plt

    from lensmount.loop.sweep import NO_ERROR_BAR, figure

    params = (Param.parse("mount.vanes.count=3,4,5"),)
    vs = [Variant(0, {"mount.vanes.count": 3}, 1.00002e-4, None), Variant(1, {"mount.vanes.count": 4}, 1.0e-4, None),
          Variant(2, {"mount.vanes.count": 5}, 1.00001e-4, None)]
    fig = figure(vs, params)
    fig.canvas.draw()
    ax = fig.axes[0]
    assert ax.get_ylim()[0] == 0 and ax.get_ylim()[1] < 1.5e0  # from 0: the 0.002 % differences stay flat
    assert ax.yaxis.get_offset_text().get_text() == "" and ax.xaxis.get_offset_text().get_text() == ""
    assert "10^-4" in ax.get_ylabel()
    ticks = [t for t in ax.get_xticks() if 3 <= t <= 5]
    assert ticks and all(float(t).is_integer() for t in ticks)
    assert any(NO_ERROR_BAR in t.get_text() for t in ax.texts)
    plt.close(fig)
