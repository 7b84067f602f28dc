"""Lens inputs: the ray-miss error names the surface the beam really fails at, and a design
folder holds exactly one lens file."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from lensmount.design.lens import load_lens
from lensmount.errors import InputError
from tests.inputs.conftest import EXAMPLES

COOKE = EXAMPLES / "cooke-triplet" / "lens.toml"


def _cooke_with_radius(tmp_path, surface: int, radius: float):
    """lens.toml of the cooke triplet with one radius changed; returns (path, line of that radius)."""
    text = COOKE.read_text()
    heads = [m.start() for m in re.finditer(r"\[\[surface\]\]", text)]
    start = heads[surface - 1]
    m = re.compile(r"radius = \S+").search(text, start)
    text = text[:m.start()] + f"radius = {radius}" + text[m.end():]
    path = tmp_path / "lens.toml"
    path.write_text(text)
    return path


def test_surface_2_at_minus_50_does_not_blame_surface_1(tmp_path):
    """The aiming used to overshoot (undamped Newton) and start rays outside surface 1, which
    was then blamed. Aimed properly every ray passes; what is wrong is element 1's edge: its
    faces cross at the height the beam needs."""
    with pytest.raises(InputError) as err:
        load_lens(_cooke_with_radius(tmp_path, 2, -50.0))
    e = err.value
    assert e.field != "surface[1].radius" and "miss surface 1" not in e.detail
    assert e.field == "surface[1].thickness" and "surfaces 1 and 2 cross" in e.detail and e.line is not None


@pytest.mark.parametrize("radius", [-435.76044, -50.0])
def test_aiming_never_strands_a_ray_outside_the_lens(tmp_path, radius):
    """Every aimed ray passes the whole lens (no ray starts where it misses surface 1); on the
    example lens every ray crosses the stop at its pupil point."""
    from lensmount.design.lens import validate
    from lensmount.optics.io.lens_toml import read_lens_toml
    from lensmount.optics.realrays import aim, pupil_rings, stop_semi_diameter, trace

    p, _ = read_lens_toml(_cooke_with_radius(tmp_path, 2, radius))
    validate(p)
    pupil = pupil_rings(4, 12, half=True)
    r_stop = stop_semi_diameter(p)
    o, d = aim(p, [0.0, 14.0, 20.0], pupil, stop_radius=r_stop)
    rays = trace(p, o, d, clip=False)
    assert not rays.vignetted.any()
    assert np.hypot(o[:, 0], o[:, 1]).max() < abs(p.surfaces[0].radius)
    if radius != -50.0:
        np.testing.assert_allclose(rays.points[p.stop_index, :, :2], np.tile(pupil * r_stop, (3, 1)), atol=1e-8)


@pytest.mark.parametrize("surface,radius", [(3, -4.0), (4, 7.0), (6, -7.0)])
def test_a_radius_the_beam_misses_is_named(tmp_path, surface, radius):
    # (3, -8) was here: the beam does meet that R −8 mm bowl (from 6 mm in front, inside its sphere,
    # which the intersection missed until it took the second root) and is lost at surface 4.
    with pytest.raises(InputError) as err:
        load_lens(_cooke_with_radius(tmp_path, surface, radius))
    assert err.value.field == f"surface[{surface}].radius" and f"miss surface {surface} " in err.value.detail


def test_both_lens_files_in_a_design_folder_is_an_error(tmp_path):
    from lensmount.design.folder import load_design

    d = tmp_path / "d"
    d.mkdir()
    for name in ("lens.toml", "mount.toml"):
        shutil.copy2(EXAMPLES / "cooke-triplet" / name, d / name)
    assert load_design(d).lens_path.name == "lens.toml"
    shutil.copy2(EXAMPLES / "cooke-triplet" / "cooke-triplet.zmx", d / "lens.zmx")
    for load in (load_design, load_lens):
        with pytest.raises(InputError) as err:
            load(d)
        assert err.value.file == str(d) and "both lens.toml and lens.zmx" in err.value.detail
