"""Draw docs/vanes-line-of-sight.png: the line-of-sight vane construction on the Cooke triplet's hood.

Run from the repository root: PYTHONPATH=src python docs/figures/vanes_line_of_sight.py
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lensmount.cad.kinds.hood import steepest_sun_slope  # noqa: E402
from lensmount.cad.layout import plan  # noqa: E402
from lensmount.design.lens import load_lens  # noqa: E402
from lensmount.design.mount import parse_mount  # noqa: E402
from lensmount.validation import parse_toml  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
EX = ROOT / "examples" / "cooke-triplet"

data = parse_toml((EX / "mount.toml").read_text(), "mount.toml")
data["vanes"]["placement"] = "line-of-sight"
spec = parse_mount(data)
p = load_lens(EX / "lens.toml")
layout = plan(p, spec)
hood = layout.part("hood").template
R, z0, z1 = hood.inner_radius, hood.z_front, hood.z_back
vanes = [v.template for v in layout.parts if v.kind == "vane" and v.template.z_front < z1]
a = layout.prescription.surfaces[0].clear_semi_diameter
za = float(layout.part("lens-1").template.front_z(a))
theta = spec.exclusion_deg(p.max_field_deg)

fig, ax = plt.subplots(figsize=(7, 7.5), dpi=110)
for sign in (1, -1):
    ax.plot([z0, z1], [sign * R, sign * R], color="k", lw=2)
    for v in vanes:
        ax.fill_between([v.z_front, v.z_front + v.thickness], sign * v.inner_radius, sign * R, color="0.35")
zz = np.linspace(z0, za, 200)
env = layout.envelope.at(zz)
ax.plot(zz, env, "--", color="tab:green", lw=1, label="beam envelope (full field, full aperture)")
ax.plot(zz, -env, "--", color="tab:green", lw=1)
ax.plot([za, za], [-a, a], color="tab:blue", lw=4, label="entrance aperture (lens 1 clear aperture)")
lands = []
for k, (v, nxt) in enumerate(zip(vanes[:-1], vanes[1:])):
    # the nearest wall point lit behind v: the steepest sun ray past every edge land so far
    lands += [(v.z_front, v.inner_radius), (v.z_front + v.edge_width, v.inner_radius)]
    z_lit = max(v.z_front + v.thickness, v.z_front + v.edge_width + (R - v.inner_radius) / steepest_sun_slope(lands))
    ax.plot([z_lit, za], [R, -a], color="tab:red", lw=0.8, label="sight line: lit wall point → far aperture edge"
            if k == 0 else None)
    ax.plot([z_lit], [R], "o", color="tab:orange", ms=5, label="nearest wall point the sun lights behind a vane"
            if k == 0 else None)
# sun rays at the exclusion angle through the mouth vane's opening
t = np.tan(np.radians(theta))
for y0 in np.linspace(-vanes[0].inner_radius, vanes[0].inner_radius, 7):
    z_hit = vanes[0].z_front + (R - y0) / t
    ax.plot([vanes[0].z_front - 3, min(z_hit, z1)], [y0 - 3 * t, y0 + (min(z_hit, z1) - vanes[0].z_front) * t],
            color="gold", lw=0.8, label=f"sun at the exclusion angle {theta:g}°" if y0 == -vanes[0].inner_radius else None)
ax.set_xlabel("z (mm)")
ax.set_ylabel("height in the meridional plane (mm)")
ax.set_title(f"Line-of-sight hood vanes, Cooke triplet example: {len(vanes)} vanes")
ax.set_aspect("equal")
ax.legend(loc="upper center", fontsize=7, bbox_to_anchor=(0.5, -0.1), ncol=2)
fig.tight_layout()
fig.savefig(ROOT / "docs" / "vanes-line-of-sight.png")
print(ROOT / "docs" / "vanes-line-of-sight.png")
