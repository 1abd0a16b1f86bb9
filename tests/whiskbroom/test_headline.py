"""Regression: the headline figures of seed 002 that docs/whiskbroom.md states, pinned to
the document's own rounding.

Both are closed-form evaluations of the nominal geometry (no Monte Carlo): the image-motion
velocity at the array centre by the complex step (exact to rounding, ~1e-13 relative) and
its drift angle. The numerical error is far below the last digit the document prints, so
the tolerance is half a unit of that digit (the document's rounding): any change beyond it
is a change of the model or of the default scenario, and the document must change with it.
"""

import math

import numpy as np
import pytest

from simcam.whiskbroom import geometry as geo
from simcam.whiskbroom import scenario as wsc
from simcam.whiskbroom import synthesis as sy


def test_array_angle_and_centre_speed_of_the_default_are_the_documented_ones():
    sc = wsc.default()
    # docs/whiskbroom.md: "the nominal drift angle at the array centre (76.406 deg at
    # gamma0 = 0)" (3 decimals: +-5e-4 deg)
    assert sc.orbit.gamma0_deg == 0.0
    assert math.degrees(sy.array_angle(sc)) == pytest.approx(76.406, abs=5e-4)
    # docs/whiskbroom.md: "|V_P| (97.2 mm/s at the centre)"; the synthesis JSON's
    # nominal_speed_mm_s prints 97.193 (3 decimals: +-5e-4 mm/s)
    v = geo.image_motion(sy.nominal_params(sc, math.radians(sc.orbit.gamma0_deg)), [0.0], [0.0])[0, 0]
    speed = float(np.hypot(*v))
    assert speed == pytest.approx(97.193, abs=5e-4)
    assert round(speed, 1) == 97.2
