"""Run as a user whose installed plug-in package is plugins/ (its dist-info declares the entry points):
a fresh process, lensmount finding the plug-ins itself. Prints what test_recipes.py checks, as JSON."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1] / "trace"))

from geometry import mech_scene, scene_dict  # noqa: E402

from lensmount.design.scene import scene_from_dict  # noqa: E402
from lensmount.errors import InputError  # noqa: E402
from lensmount.integrators.registry import check_method, integrator  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.scene import primitives  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def error_of(call) -> dict:
    try:
        call()
    except InputError as err:
        return {"field": err.field, "detail": err.detail, "valid": err.valid}
    return {}


out: dict = {}

# BSDF: named by a scene's [finishes], its parameters checked by its own model; E[weight] = albedo = ρ.
tube = primitives.tube(-5.0, 60.0, 15.0, 16.0)
paint = {"paint": {"model": "uniform-diffuse", "reflectance": 0.3}}
scene = mech_scene(tube, finishes=paint, assign={"*": "paint"})
bsdf = scene.bsdf_of_tag[0]
u = np.random.default_rng(1).random((200_000, 2))
n = np.tile([0.0, 0.0, 1.0], (len(u), 1))
wi = np.tile([math.sin(0.5), 0.0, math.cos(0.5)], (len(u), 1))
wo, weight, pdf = bsdf.sample(wi, n, u)
out["bsdf"] = {"type": type(bsdf).__name__, "reflectance": bsdf.reflectance,
               "mean_weight": float(weight.mean()), "weight_se": float(weight.std() / math.sqrt(len(u))),
               "weight_is_f_cos_over_pdf": bool(np.allclose(weight, bsdf.eval(wi, wo, n) * wo[:, 2] / pdf)),
               "pdf_matches": bool(np.allclose(pdf, bsdf.pdf(wi, wo, n)))}
out["bsdf_error"] = error_of(lambda: scene_from_dict(scene_dict(
    finishes={"paint": {"model": "uniform-diffuse", "reflectance": 1.5}}, assign={"*": "paint"})))

# Source: read from the scene's [source] with its own keys; its flux through an open tube is π r².
out["source_keys_error"] = error_of(lambda: scene_from_dict(scene_dict(
    source={"type": "beam", "off_axis_deg": 0.0, "beam_radius": 2.0})))
out["source_other_kind_error"] = error_of(lambda: scene_from_dict(scene_dict(
    source={"type": "beam", "off_axis_deg": 0.0, "beam_radius_mm": 2.0, "limb_darkening": True})))
detector = {"width_mm": 20.0, "height_mm": 20.0, "pixels": [4, 4], "z_mm": 50.0}
out["beam_flux"] = []
for off_axis in (0.0, 5.0):
    beam = mech_scene(tube, detector=detector,
                      source={"type": "beam", "off_axis_deg": off_axis, "azimuth_deg": 90.0, "beam_radius_mm": 2.0})
    est = integrator("forward").run_pass(beam, Tracer(beam), 0, 20_000, 3)
    out["beam_flux"].append(float(est.part_flux.sum()))

# Integrator: by its name, as `simulate --method` asks; on a scene without ghosts it is forward, photon for photon.
check_method("light-tracing")
lit = mech_scene(tube, detector=detector, finishes=paint, assign={"*": "paint"},
                 source={"type": "sun", "off_axis_deg": 5.0, "azimuth_deg": 90.0},
                 effects={"scatter": True, "ghosts": False, "direct": True})
images = {m: integrator(m).run_pass(lit, Tracer(lit), 1, 20_000, 7) for m in ("light-tracing", "forward")}
out["integrator"] = {"same_image": bool(np.array_equal(images["light-tracing"].image, images["forward"].image)),
                     "flux": float(images["forward"].part_flux.sum())}
out["integrator_params_error"] = error_of(lambda: integrator("light-tracing", params={"batch": 10}))
print(json.dumps(out))
