"""Shop drawings: one dimensioned half-section per part, as SVG and DXF (`parts/NAME.svg|.dxf`).

Every built-in part is turned (a solid of revolution), so its drawing is the half section
r >= 0 of the exported solid, the axis horizontal (x = z − the part's front z, y = r) at
1:1 in mm, the centre line dash-dotted. The dimensions a turner needs come from the part's
template (the layout's numbers, never measured back from the drawing): bores and outside
as diameters (Ø, left of the part), axial lengths below the axis, the knife-edge land's
width, the bevel's angle, each with the ± tolerance of mount.toml's `[drawing]` table.
A title block names the part, its material and finish, the scale and the general tolerance.

Geometry (section, centre line, dimension and extension lines, arrowheads) goes through
build123d's `ExportSVG` / `ExportDXF`; the labels are real text (SVG `<text>`, DXF TEXT),
so a CAD program or a script reads them as text. build123d's own `ExtensionLine` draws
its labels as glyph outlines after a boolean per glyph (~1 s per dimension, 150 dimensions
on the reference), so the lines here are drawn directly.
"""

from __future__ import annotations

import io
import math

import numpy as np
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from lensmount.atomic import atomic_path
from lensmount.templates.barrel import Barrel
from lensmount.templates.cell import Cell, SpiderCell
from lensmount.templates.diaphragm import Diaphragm
from lensmount.templates.hood import Hood
from lensmount.templates.housing import Housing
from lensmount.templates.lens_element import LensElement
from lensmount.templates.mirror import MirrorElement
from lensmount.templates.rear_baffle import RearBaffle
from lensmount.templates.retainer import Retainer
from lensmount.templates.spacer import Spacer
from lensmount.templates.vane import Vane

LAYERS = ("profile", "axis", "dimensions")


@dataclass(frozen=True)
class Dimension:
    """One dimension on a part drawing, in the assembly frame (r, z in mm).

    Args:
        name: what it measures, in the machinist's words ("bore", "outside", "length", ...).
        kind: `diameter` (value 2r of the feature at (r, z0)), `length` (z1 − z0, extension
            lines from (r0, z0) and (r1, z1)), `angle` (value in degrees, a leader to (r0, z0))
            or `radius` (a lens face's radius of curvature, a leader to its vertex; the optical
            shop's tolerance is in fringes, not given here).
        value: mm (degrees for an angle).
        tolerance: ± the same unit.
    """

    name: str
    kind: str
    value: float
    tolerance: float
    z0: float
    r0: float
    z1: float = 0.0
    r1: float = 0.0

    @property
    def label(self) -> str:
        if self.kind == "angle":
            return f"{self.name} {self.value:.1f}° ±{self.tolerance:g}°"
        if self.kind == "radius":
            return f"{self.name} {'flat' if math.isinf(self.value) else f'{self.value:.3f}'}"
        prefix = "Ø" if self.kind == "diameter" else ""
        return f"{self.name} {prefix}{self.value:.3f} ±{self.tolerance:g}"


def _dia(name, r, z, tol):
    return Dimension(name, "diameter", 2.0 * float(r), tol.diameter_mm, float(z), float(r))


def _len(name, z0, r0, z1, r1, tol, t=None):
    return Dimension(name, "length", float(z1 - z0), tol.length_mm if t is None else t,
                     float(z0), float(r0), float(z1), float(r1))


def _angle(name, deg, r, z, tol):
    return Dimension(name, "angle", float(deg), tol.angle_deg, float(z), float(r))


def dimensions(plan, tol, prescription=None) -> list[Dimension]:
    """The dimensions of one planned part (PartPlan) from its template's numbers.

    tol: the `[drawing]` table (diameter_mm, length_mm, land_mm, angle_deg).
    """
    t = plan.template
    if isinstance(t, Vane):
        w = min(t.edge_width, t.thickness)
        return [_dia("bore", t.inner_radius, t.z_front, tol), _dia("outside", t.outer_radius, t.z_front + t.thickness, tol),
                _len("thickness", t.z_front, t.outer_radius, t.z_front + t.thickness, t.outer_radius, tol),
                _len("land", t.z_front, t.inner_radius, t.z_front + w, t.inner_radius, tol, tol.land_mm),
                _angle("bevel", t.bevel_angle_deg, t.inner_radius, t.z_front + w, tol)]
    if isinstance(t, Diaphragm):
        z0, z1 = t.z_range()
        zl = z0 if t.bevel_side == "rear" else z1 - t.land  # the land's front end
        R, r0, run = t.outer_radius, t.inner_radius, t.bevel_run()
        z_bevel = 0.5 * (zl + t.land + z1) if t.bevel_side == "rear" else 0.5 * (z0 + zl)  # its middle
        return [_dia("bore", r0, zl, tol), _dia("outside", R, z0 + t.slope * (R - r0), tol),
                _len("thickness", z0, r0, z1, r0, tol),
                _len("land", zl, r0, zl + t.land, r0, tol, tol.land_mm),
                _angle("bevel", t.bevel_angle_deg, r0 + 0.5 * run, z_bevel + t.slope * 0.5 * run, tol)]
    if isinstance(t, Hood):
        out = [_dia("bore", t.inner_radius, t.z_front, tol), _dia("outside", t.outer_radius, t.z_back, tol),
               _len("length", t.z_front, t.outer_radius, t.z_back, t.outer_radius, tol)]
        if t.flange_radius is not None:
            out += [_dia("flange bore", t.flange_radius, t.z_back, tol),
                    _len("flange", t.z_back - t.flange_thickness, t.flange_radius, t.z_back, t.flange_radius, tol)]
        return out
    if isinstance(t, Housing):
        z_end = t.z_back_wall + t.wall
        out = [_dia("bore", t.inner_radius, t.z_back_wall, tol), _dia("outside", t.inner_radius + t.wall, z_end, tol),
               _len("length", t.z_front, t.inner_radius + t.wall, z_end, t.inner_radius + t.wall, tol),
               _len("depth", t.z_front, t.inner_radius, t.z_back_wall, t.inner_radius, tol)]
        if t.flange_radius is not None:
            out.append(_dia("flange bore", t.flange_radius, t.z_front, tol))
        return out
    if isinstance(t, Spacer):
        R = t.outer_radius
        out = [_dia("front bore", t.front_r, t.front_z, tol), _dia("rear bore", t.back_r, t.back_z, tol),
               _dia("outside", R, t.front_face_z(R), tol),
               _len("length", t.front_z, t.front_r, t.back_z, t.back_r, tol)]
        if t.tube_radius is not None:
            out += [_dia("tube bore", t.tube_radius, t.front_z + t.lip, tol),
                    _len("lip", t.front_z, t.front_r, t.front_z + t.lip, t.front_r, tol)]
        return out
    if isinstance(t, Retainer):
        zf, R = t.far_face_z(), t.outer_radius
        zc = float(t.contact_face_z(R))
        far = t.contact_r if t.far_r is None else t.far_r
        return [_dia("contact bore", t.contact_r, t.contact_z, tol), _dia("far bore", far, zf, tol),
                _dia("outside (thread)", R, zc, tol), _len("thickness", min(zc, zf), R, max(zc, zf), R, tol)]
    if isinstance(t, Barrel):
        pts = list(t.bore)
        out = [_dia("outside", t.outer_radius, pts[0][1], tol),
               _len("length", pts[0][1], t.outer_radius, pts[-1][1], t.outer_radius, tol)]
        for (ra, za), (rb, zb) in zip(pts[:-1], pts[1:]):
            if abs(ra - rb) < 1e-9 and zb - za > 1e-6:  # a cylindrical bore: a seat or a lip
                out += [_dia("bore", ra, 0.5 * (za + zb), tol), _len("bore length", za, ra, zb, rb, tol)]
        return out
    if isinstance(t, RearBaffle):
        pts = t.bore
        out = [_dia("outside", t.outer_radius, t.z_front, tol),
               _len("length", t.z_front, t.outer_radius, t.z_back, t.outer_radius, tol)]
        for name, (r, z) in (("front bore", pts[0]), ("rear bore", pts[-1])):
            out.append(_dia(name, r, z, tol))
        return out
    if isinstance(t, LensElement):
        R = t.outer_radius
        ze0, ze1 = t.edge_z()
        out = [_dia("edge", R, 0.5 * (ze0 + ze1), tol),
               _len("centre thickness", t.front.z_vertex, 0.0, t.back.z_vertex, 0.0, tol),
               _len("edge thickness", ze0, R, ze1, R, tol)]
        for name, face in (("R1", t.front), ("R2", t.back)):
            radius = math.inf if face.curvature == 0 else 1.0 / face.curvature
            out.append(Dimension(name, "radius", radius, 0.0, face.z_vertex, 0.0))
        return out
    if isinstance(t, MirrorElement):
        R, h = t.outer_radius, t.hole_radius
        zf, zb = float(t.front_z(R)), float(t.back_z(R))
        out = [_dia("edge", R, 0.5 * (zf + zb), tol), _len("edge thickness", zf, R, zb, R, tol)]
        if h > 0:
            out.append(_dia("hole", h, 0.5 * (float(t.front_z(h)) + float(t.back_z(h))), tol))
        for name, face in (("R1", t.front), ("R2", t.back)):
            if face is not None:
                radius = math.inf if face.curvature == 0 else 1.0 / face.curvature
                out.append(Dimension(name, "radius", radius, 0.0, face.z_vertex, 0.0))
        return out
    if isinstance(t, Cell):
        pts = np.asarray(t.outline, dtype=np.float64)
        (r_in, z0), (r_out, z1) = pts.min(0), pts.max(0)
        out = [_dia("outside", r_out, z0, tol), _dia("bore", r_in, z0, tol), _len("length", z0, r_out, z1, r_out, tol)]
        if isinstance(t, SpiderCell):
            out.append(_dia("vane tips", t.reach, 0.5 * (z0 + z1), tol))
        return out
    return []  # a kind with no template dimensions: the drawing still shows its section


def _half_section(solid, z_front: float):
    """The solid's section in the half plane r >= 0, in drawing coordinates (x = z − z_front, y = r)."""
    from build123d import Keep, Plane  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

    faces = []
    for f in solid.intersect(Plane.XZ).faces():
        box = f.bounding_box()
        if box.max.X <= 1e-9:
            continue  # the other half
        if box.min.X < -1e-9:  # a part that crosses the axis (a lens, the housing's back wall)
            f = f.split(Plane.YZ, keep=Keep.TOP)
        faces += f.faces()
    plane = Plane(origin=(0.0, 0.0, z_front), x_dir=(0.0, 0.0, 1.0), z_dir=(0.0, 1.0, 0.0))
    return [plane.to_local_coords(f) for f in faces]


@dataclass
class _Sheet:
    """Lines (build123d Edges by layer) and texts ((x, y, height, text, anchor)) of one drawing."""

    edges: dict
    texts: list

    def line(self, layer, a, b):
        from build123d import Edge  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

        if math.dist(a, b) > 1e-9:
            self.edges[layer].append(Edge.make_line((a[0], a[1], 0.0), (b[0], b[1], 0.0)))

    def arrow(self, tip, toward, size):
        """An open arrowhead at tip pointing away from `toward`."""
        dx, dy = tip[0] - toward[0], tip[1] - toward[1]
        n = math.hypot(dx, dy) or 1.0
        ux, uy = dx / n, dy / n
        for s in (+1, -1):
            back = (tip[0] - size * ux - 0.3 * size * s * uy, tip[1] - size * uy + 0.3 * size * s * ux)
            self.line("dimensions", tip, back)


def _layout_sheet(sections, dims: list[Dimension], z_front: float, title: list[str]) -> _Sheet:
    """Place the section, centre line, dimensions and title block on one sheet."""
    sheet = _Sheet({k: [] for k in LAYERS}, [])
    boxes = [f.bounding_box() for f in sections]
    x_lo = min(b.min.X for b in boxes) if boxes else 0.0
    x_hi = max(b.max.X for b in boxes) if boxes else 1.0
    r_hi = max(b.max.Y for b in boxes) if boxes else 1.0
    size = max(x_hi - x_lo, r_hi, 1.0)
    h = min(max(size / 40.0, 1.0), 4.0)  # text height: legible from a 10 mm ring to a 400 mm barrel
    gap, step, arrow = 0.5 * h, 2.2 * h, 0.8 * h
    sheet.line("axis", (x_lo - 2 * h, 0.0), (x_hi + 2 * h, 0.0))
    n_dia = n_len = n_note = 0
    for d in dims:
        if d.kind == "diameter":
            x = x_lo - 3 * h - n_dia * step
            p = (d.z0 - z_front, d.r0)
            sheet.line("dimensions", (p[0] - gap if p[0] > x else p[0] + gap, p[1]), (x - gap, p[1]))
            sheet.line("dimensions", (x, 0.0), (x, p[1]))
            sheet.arrow((x, p[1]), (x, 0.0), arrow)
            sheet.texts.append((x - 0.3 * h, p[1], h, d.label, "vertical"))  # reads upward, ends at the feature
            n_dia += 1
        elif d.kind == "length":
            y = -3 * h - n_len * step
            a, b = (d.z0 - z_front, d.r0), (d.z1 - z_front, d.r1)
            for p in (a, b):
                sheet.line("dimensions", (p[0], p[1] - gap if p[1] > y else p[1]), (p[0], y - gap))
            sheet.line("dimensions", (a[0], y), (b[0], y))
            if abs(b[0] - a[0]) > 2.5 * arrow:  # arrows inside
                sheet.arrow((a[0], y), (b[0], y), arrow)
                sheet.arrow((b[0], y), (a[0], y), arrow)
            else:  # a narrow land: arrows outside, pointing in
                lo, hi = min(a[0], b[0]), max(a[0], b[0])
                sheet.line("dimensions", (lo - 2 * arrow, y), (lo, y))
                sheet.line("dimensions", (hi, y), (hi + 2 * arrow, y))
                sheet.arrow((lo, y), (lo - 2 * arrow, y), arrow)
                sheet.arrow((hi, y), (hi + 2 * arrow, y), arrow)
            sheet.texts.append((max(a[0], b[0]) + 2.5 * arrow, y - 0.35 * h, h, d.label, "start"))
            n_len += 1
        else:  # angle, radius: a leader from the note to the feature
            p = (d.z0 - z_front, d.r0)
            note = (x_hi + 3 * h, r_hi - n_note * step)
            sheet.line("dimensions", (note[0] - 0.3 * h, note[1] + 0.3 * h), p)
            sheet.texts.append((note[0], note[1], h, d.label, "start"))
            n_note += 1
    y = -3 * h - (n_len + 1) * step
    for k, line in enumerate(title):
        sheet.texts.append((x_lo - 3 * h - max(n_dia - 1, 0) * step, y - k * 1.5 * h, h, line, "start"))
    # a frame around everything: it fixes the sheet's extent for both exporters
    boxes = [_text_box(*t) for t in sheet.texts] + [(x_lo, 0.0, x_hi, r_hi)]
    x0, y0 = min(b[0] for b in boxes) - 2 * h, min(b[1] for b in boxes) - 2 * h
    x1, y1 = max(b[2] for b in boxes) + 2 * h, max(b[3] for b in boxes) + 2 * h
    for a, b in (((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))):
        sheet.line("dimensions", a, b)
    return sheet


def _text_box(x, y, h, text, anchor):
    """(x0, y0, x1, y1) a label covers (glyphs ~0.6 h wide)."""
    length = 0.6 * h * len(text)
    if anchor == "vertical":
        return x - 1.2 * h, y - length, x, y
    return x, y - 0.3 * h, x + length, y + h


def _drawn(exp, sections, sheet: _Sheet):
    """The profile, axis and dimension lines on their layers of an SVG or DXF exporter (same API)."""
    from build123d import LineType  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

    exp.add_layer("profile", line_weight=0.35)
    exp.add_layer("axis", line_weight=0.13, line_type=LineType.DASHDOT)
    exp.add_layer("dimensions", line_weight=0.13)
    exp.add_shape(sections, layer="profile")
    for layer in ("axis", "dimensions"):
        exp.add_shape(sheet.edges[layer], layer=layer)
    return exp


def _svg_bytes(sections, sheet: _Sheet) -> bytes:
    from build123d import ExportSVG  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

    exp = _drawn(ExportSVG(margin=1.0), sections, sheet)
    buf = io.BytesIO()
    exp.write(buf)
    root = ET.fromstring(buf.getvalue())
    ns = "http://www.w3.org/2000/svg"
    ET.register_namespace("", ns)
    group = ET.SubElement(root, f"{{{ns}}}g", {"id": "labels", "font-family": "sans-serif", "fill": "black"})
    for x, y, h, text, anchor in sheet.texts:
        attrs = {"x": f"{x:.4f}", "y": f"{-y:.4f}", "font-size": f"{h:.3f}"}
        if anchor == "vertical":  # reads upward left of a diameter's dimension line, ends at the feature
            attrs.update({"text-anchor": "end", "transform": f"rotate(-90 {x:.4f} {-y:.4f})"})
        el = ET.SubElement(group, f"{{{ns}}}text", attrs)
        el.text = text
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def _dxf_text(sections, sheet: _Sheet) -> str:
    import ezdxf  # lazy: ezdxf takes ~1 s to load; only the DXF drawing needs it
    from build123d import ExportDXF
    from ezdxf.enums import TextEntityAlignment

    exp = _drawn(ExportDXF(), sections, sheet)
    buf = io.BytesIO()
    exp.write(buf)
    doc = ezdxf.read(io.StringIO(buf.getvalue().decode("utf-8")))
    msp = doc.modelspace()
    for x, y, h, text, anchor in sheet.texts:
        if anchor == "vertical":
            entity = msp.add_text(text, dxfattribs={"layer": "dimensions", "height": h, "rotation": 90.0})
            entity.set_placement((x, y), align=TextEntityAlignment.BOTTOM_RIGHT)
        else:
            msp.add_text(text, dxfattribs={"layer": "dimensions", "height": h, "insert": (x, y)})
    out = io.StringIO()
    doc.write(out)
    return out.getvalue()


def write_drawing(solid, dims: list[Dimension], title: list[str], svg_path: Path, dxf_path: Path) -> None:
    """Write the part's dimensioned half section as SVG and DXF (each atomically)."""
    z_front = float(solid.bounding_box().min.Z)
    sections = _half_section(solid, z_front)
    sheet = _layout_sheet(sections, dims, z_front, title)
    svg = _svg_bytes(sections, sheet)
    dxf = _dxf_text(sections, sheet)
    with atomic_path(svg_path) as tmp:
        tmp.write_bytes(svg)
    with atomic_path(dxf_path) as tmp:
        tmp.write_text(dxf, encoding="utf-8")


def title_block(name: str, kind: str, material: str, finish: str, tol) -> list[str]:
    return [f"{name} ({kind})  material: {material}  finish: {finish}",
            "scale 1:1  dimensions in mm, half section (turned part, axis dash-dotted)",
            f"unless stated: lengths ±{tol.length_mm:g}  diameters ±{tol.diameter_mm:g}  angles ±{tol.angle_deg:g}°"]


__all__ = ["Dimension", "dimensions", "write_drawing", "title_block"]
