"""What the connection through the optics carries on a design at one angle, per pass: detector flux by the
walk's own connections and by the connections through the optics, how many scatters started one and how
many landed. python benchmarks/through_optics/through_optics_share.py DESIGN SCENE ANGLE PASSES PHOTONS SEED"""

import dataclasses
import sys
from pathlib import Path

import numpy as np

import lensmount.integrators.bidirectional as bidirectional
from lensmount.integrators.settings import EstimatorSettings
from lensmount.loop.prepare import build, read_inputs
from lensmount.scene.build import make_source
from lensmount.trace.tracer import Tracer

design_dir, scene_file, angle, passes, photons, seed = (Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3]),
                                                        int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6]))
design, spec = read_inputs(design_dir, scene_file)
base = build(design, spec, None).scene
scene = dataclasses.replace(base, source=make_source(spec.source.model_copy(update={"off_axis_deg": angle}),
                                                      base.front_opening, base.mesh, base.detector, design.prescription))
tracer = Tracer(scene)
tally = {}
real_connect = bidirectional.connect_to_detector
real_through = bidirectional.connections_through_optics


class Counting:
    def __init__(self, film, key):
        self.film, self.key = film, key
        self.channel_of_tag = film.channel_of_tag

    def deposit(self, pixel, value, *rest):
        tally[self.key] = tally.get(self.key, 0.0) + float(np.sum(value))
        self.film.deposit(pixel, value, *rest)


real_share = bidirectional._walk_share
last_share = []


def share(*args):
    s = real_share(*args)
    last_share[:] = [s]
    return s


def connect(scene, tracer, film, position, direction, normal, flux, *rest):
    if rest[-1].endswith("/through-optics"):
        real_connect(scene, tracer, Counting(film, "through-optics"), position, direction, normal, flux, *rest)
        real_connect(scene, tracer, Counting(Null(film), "through-optics-alone"), position, direction, normal,
                     flux / alone[-1][0].share, *rest)
        return
    s = last_share[0] if last_share else np.ones(len(flux))
    last_share[:] = []
    mixed = s < 1  # the photons whose way the connection through the optics also samples
    real_connect(scene, tracer, Counting(film, "walk-other"), position, direction, normal, np.where(mixed, 0.0, flux), *rest)
    real_connect(scene, tracer, Counting(film, "walk-class"), position, direction, normal, np.where(mixed, flux, 0.0), *rest)
    real_connect(scene, tracer, Counting(Null(film), "walk-class-alone"), position, direction, normal,
                 np.where(mixed, flux / s, 0.0), *rest)


class Null:
    def __init__(self, film):
        self.channel_of_tag = film.channel_of_tag

    def deposit(self, *a):
        pass


def through(scene, tracer, cells, aim, v, *rest):
    a = real_through(scene, tracer, cells, aim, v, *rest)
    tally["starts"] = tally.get("starts", 0) + len(v.flux)
    tally["landed"] = tally.get("landed", 0) + len(a.rows)
    tally["alone"] = tally.get("alone", 0.0)
    alone.append((a, v))
    return a


alone = []


bidirectional.connect_to_detector = connect
bidirectional.connections_through_optics = through
bidirectional._walk_share = share
m = bidirectional.Bidirectional(EstimatorSettings(view_map_pitch=spec.run.view_map_pitch, connect_through_optics=True))
for i in range(passes):
    tally.clear()
    total = m.run_pass(scene, tracer, i, photons, seed).flux
    print(f"{angle:.0f}° pass {i}: total {total:.3e}  walk-connect {tally.get('walk', 0):.3e}  "
          f"through-optics {tally.get('through-optics', 0):.3e} (alone {tally.get('through-optics-alone', 0):.3e}) | class by walk {tally.get('walk-class', 0):.3e} "
          f"(alone {tally.get('walk-class-alone', 0):.3e}) other {tally.get('walk-other', 0):.3e}  starts {tally.get('starts', 0)} "
          f"landed {tally.get('landed', 0)}", flush=True)
