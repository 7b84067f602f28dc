"""Bulk absorption from the catalogue: Beer-Lambert against the catalogue's own 25 mm measurements."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from lensmount.errors import InputError
from lensmount.optics.glass import _find_catalogue_glass, internal_transmittance


@pytest.mark.parametrize("glass", ["N-BK7", "N-SF6", "F2"])
def test_ten_mm_data_scaled_to_25_mm_matches_the_catalogues_25_mm_measurement(glass):
    # Schott measures internal transmittance on 10 mm and on 25 mm samples; exp(-a L) with a from the
    # 10 mm column must give the 25 mm column to the tables' 3-digit rounding (amplified 2.5x).
    data = _find_catalogue_glass(glass).glass_data()
    pairs = []
    for key in data.index:
        if "TAUI25/" in str(key[1]):
            wl_nm = float(str(key[1]).split("/")[1])
            t25 = pd.to_numeric(pd.Series([data[key]]), errors="coerce").iloc[0]
            if np.isfinite(t25) and 0.05 < t25:
                pairs.append((wl_nm / 1000.0, float(t25)))
    assert len(pairs) >= 10
    wl, t25 = np.array(pairs).T
    assert np.max(np.abs(internal_transmittance(glass, wl, 25.0) - t25)) < 0.004


def test_transmittance_shapes_limits_and_lossless_materials():
    t = internal_transmittance("N-BK7", np.array([0.4, 0.55, 0.7])[:, None], np.array([0.0, 10.0, 1000.0]))
    assert t.shape == (3, 3) and np.all(np.isfinite(t))
    assert np.all(t[:, 0] == 1.0) and np.all(np.diff(t, axis=1) <= 0.0)        # more glass, less light
    assert internal_transmittance("N-BK7", 0.55, -5.0) == 1.0                   # no negative path
    assert internal_transmittance("N-BK7", 0.2, 10.0) >= 0.0                    # below the table: held, finite
    for lossless in ("AIR", "1.5168/64.17", "SILICA"):
        assert np.all(internal_transmittance(lossless, [0.4, 0.6], 50.0) == 1.0)
    with pytest.raises(InputError):
        internal_transmittance("NOT-A-GLASS", 0.55, 1.0)
