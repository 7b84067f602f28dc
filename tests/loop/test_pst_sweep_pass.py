"""A sweep's pass over several sources gives each source the pass it would get alone, whether the
integrator splits its pass at a source-independent view (bidirectional) or runs it whole (forward)."""

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "trace"))

from geometry import mech_scene  # noqa: E402

from lensmount.integrators.registry import SourceIndependentView, integrator  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.loop.pst import SourcesJob, sweep_pass  # noqa: E402
from lensmount.scene import primitives  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


@pytest.mark.parametrize("method,splits", [("forward", False), ("bidirectional", True)])
def test_each_source_of_a_sweep_pass_reads_as_its_pass_alone(method, splits):
    tube = primitives.tube(-5.0, 60.0, 15.0, 16.0)
    detector = {"width_mm": 20.0, "height_mm": 20.0, "pixels": [6, 6], "z_mm": 50.0}
    scenes = [mech_scene(tube, detector=detector, finishes={"paint": {"model": "lambertian", "reflectance": 0.5}},
                         assign={"*": "paint"}, source={"type": "sun", "off_axis_deg": a, "azimuth_deg": 90.0})
              for a in (2.0, 9.0)]
    base, tracer, settings = scenes[0], Tracer(scenes[0]), EstimatorSettings()
    assert isinstance(integrator(method, settings), SourceIndependentView) == splits
    swept = sweep_pass(base, tracer, SourcesJob(method, 3000, 4, 1, settings,
                                                {k: s.source for k, s in enumerate(scenes)}))
    for k, scene in enumerate(scenes):
        alone = integrator(method, settings).run_pass(dataclasses.replace(base, source=scene.source), tracer, 1,
                                                      3000, 4).totals()
        assert np.array_equal(swept[k].part_flux, alone.part_flux) and swept[k].flux == alone.flux
    assert swept[0].flux != swept[1].flux and swept[1].flux > 0
