"""User templates: CadQuery and build123d results are accepted, converted and checked."""

import math
from pathlib import Path

import pytest

from lensmount.cad.assembly import build_parts, check_user_parts
from lensmount.errors import GeometryError, InputError

CQ_HOOD = '''
import cadquery as cq

def make_part(name, params):
    ri, ro = params["inner_radius"], params["outer_radius"]
    length = params["z_back"] - params["z_front"]
    return (cq.Workplane("XY").workplane(offset=params["z_front"])
            .circle(ro).circle(ri).extrude(length))
'''

B3D_VANE = '''
from build123d import Align, BuildPart, Cylinder, Locations, Mode

def make_part(name, params):
    a = (Align.CENTER, Align.CENTER, Align.MIN)
    with BuildPart() as p:
        with Locations((0, 0, params["z_front"])):
            Cylinder(params["outer_radius"], params["thickness"], align=a)
            Cylinder(params["inner_radius"], params["thickness"], align=a, mode=Mode.SUBTRACT)
    return p.part
'''

FAT_HOOD = CQ_HOOD.replace('ri, ro = params["inner_radius"], params["outer_radius"]',
                           'ri, ro = params["inner_radius"] - 3.0, params["outer_radius"]')


def _write(tmp_path: Path, name: str, text: str) -> Path:
    f = tmp_path / name
    f.write_text(text)
    return f


def test_cadquery_hood_and_build123d_vane(reference_layout, tmp_path):
    layout, spec = reference_layout
    paths = {"hood": _write(tmp_path, "hood.py", CQ_HOOD), "vane": _write(tmp_path, "vane.py", B3D_VANE)}
    parts = {bp.name: bp for bp in build_parts(layout, spec, paths)}
    h = layout.part("hood").template
    expected = math.pi * (h.outer_radius**2 - h.inner_radius**2) * (h.z_back - h.z_front)
    assert parts["hood"].solid.volume == pytest.approx(expected, rel=1e-9)
    assert parts["hood"].user_template == paths["hood"]
    v = layout.part("vane-1").template
    expected = math.pi * (v.outer_radius**2 - v.inner_radius**2) * v.thickness
    assert parts["vane-1"].solid.volume == pytest.approx(expected, rel=1e-9)
    assert {r for r, _ in parts["vane-1"].roles} <= {"mount", "vane-edge"}
    assert parts["lens-1"].user_template is None
    check_user_parts(list(parts.values()))  # they fit


def test_user_part_that_overlaps_is_reported(reference_layout, tmp_path):
    layout, spec = reference_layout
    parts = build_parts(layout, spec, {"hood": _write(tmp_path, "hood.py", FAT_HOOD)})
    with pytest.raises(GeometryError) as exc:
        check_user_parts(parts)
    text = exc.value.paragraph()
    assert "hood" in text and "vane-" in text and "overlap" in text


def test_user_template_without_make_part(reference_layout, tmp_path):
    layout, spec = reference_layout
    with pytest.raises(InputError) as exc:
        build_parts(layout, spec, {"hood": _write(tmp_path, "hood.py", "x = 1\n")})
    assert exc.value.field == "templates.hood"


ROLE_VANE = B3D_VANE + '''

def face_role(name, params, r, z):
    """The bore is the knife edge; the rest keeps the built-in profile's tags."""
    return "vane-edge" if abs(r - params["inner_radius"]) < 1e-6 else None
'''


def test_a_template_declares_its_faces_roles(reference_layout, tmp_path):
    """Without face_role the plain cylindrical bore of a user vane lies off the built-in profile
    (which bevels after a 0.1 mm land) and is tagged mount; with it the bore is the vane edge."""
    import dataclasses

    import numpy as np

    layout, spec = reference_layout
    vanes = dataclasses.replace(layout, parts=[p for p in layout.parts if p.name == "vane-1"])
    r0 = layout.part("vane-1").template.inner_radius

    def bore_roles(text):
        bp = build_parts(vanes, spec, {"vane": _write(tmp_path, "vane.py", text)})[0]
        at_bore = [np.isclose(np.hypot(f.position_at(0.5, 0.5).X, f.position_at(0.5, 0.5).Y), r0)
                   for f in bp.solid.faces()]
        return {role for (role, _), b in zip(bp.roles, at_bore) if b}, {role for (role, _), b in zip(bp.roles, at_bore) if not b}

    plain_bore, _ = bore_roles(B3D_VANE)
    assert plain_bore == {"mount"}
    declared_bore, others = bore_roles(ROLE_VANE)
    assert declared_bore == {"vane-edge"} and others == {"mount"}
    with pytest.raises(InputError) as exc:
        bore_roles(ROLE_VANE.replace('"vane-edge" if', '"edge" if'))
    assert exc.value.field == "templates.vane" and "vane-edge" in exc.value.paragraph()
