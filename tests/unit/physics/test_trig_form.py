"""N(t)/m in eq. 7's form (two sine–cosine pairs) against the trig row's three cosines (kernels/trig.py).

The event kernels evaluate an N row as c − (g − κ sin α) sin θ; the three-cosine sum the row also holds is the
reference's form (kinematics.normal_force_per_mass). Both must give the same N, N′ and N″ to rounding.
"""

from __future__ import annotations

import math

import numpy as np

from millctl.physics.agreement import random_scenes
from millctl.physics.kernels.layout import _FORM_MARGIN, _T_N_FORM, _TRIG_COLUMNS, scene_row
from millctl.physics.kernels.telemetry import _slip_rows
from millctl.physics.kernels.trig import _trig, _trig012, _trig_bound, _trig_rows
from millctl.physics.model import MillModel


def _both_forms(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = int(row[8])
    eq7 = _trig_rows(row, n).copy()
    cosines = eq7.copy()
    cosines[:, _T_N_FORM] = 0.0
    return eq7, cosines


def _check(model: MillModel) -> None:
    rng = np.random.default_rng(40)
    for scene in random_scenes(model, 40, 40):
        eq7, cosines = _both_forms(scene_row(scene))
        assert np.all(eq7[:, _T_N_FORM] == 1.0)
        for i in range(eq7.shape[0]):
            scales = [eq7[i, 0] + _trig_bound(eq7, i, order) for order in range(3)]
            for t in rng.uniform(0.0, 5.0, 8):
                for sign in (1.0, -1.0):
                    for order in (0, 1):
                        a, b = _trig(eq7, i, t, order, sign), _trig(cosines, i, t, order, sign)
                        assert abs(a - b) <= 1e-12 * scales[order], (scene, i, t, order)
                    pair = zip(_trig012(eq7, i, t, sign), _trig012(cosines, i, t, sign), scales, strict=True)
                    for a, b, scale in pair:
                        assert abs(a - b) <= 1e-12 * scale, (scene, i, t)
                assert math.isfinite(_trig(eq7, i, t, 2, 1.0))


def test_eq7_form_is_the_three_cosines_corrected(set_a_corrected: MillModel) -> None:
    _check(set_a_corrected)


def test_eq7_form_is_the_three_cosines_paper(set_a_paper: MillModel) -> None:
    _check(set_a_paper)



def test_slip_margin_form_is_its_three_cosines(set_a_corrected: MillModel) -> None:
    """The no-slip margins μN/m ∓ F_t/m (kernels/telemetry.py) in the product form c − g_eff (μ sin θ ∓ cos θ).

    Their rows also hold the merged three cosines (the form the held-arc skip and the bounds read); a sign or a
    phase wrong in the product form makes the margin, its slope or its curvature differ from them.
    """
    rng = np.random.default_rng(41)
    for scene in random_scenes(set_a_corrected, 40, 41):
        for mu in (0.0, 0.3, 1.2):
            theta0 = float(rng.uniform(-math.pi, math.pi))
            product = _slip_rows(scene_row(scene), theta0, mu, np.zeros((2, _TRIG_COLUMNS)))
            assert np.all(product[:, _T_N_FORM] == _FORM_MARGIN)
            cosines = product.copy()
            cosines[:, _T_N_FORM] = 0.0
            for i in range(2):
                scales = [abs(product[i, 0]) + _trig_bound(product, i, order) for order in range(3)]
                for t in rng.uniform(0.0, 2.0, 8):
                    assert abs(_trig(product, i, t, 0, 1.0) - _trig(cosines, i, t, 0, 1.0)) <= 1e-12 * scales[0]
                    assert abs(_trig(product, i, t, 1, -1.0) - _trig(cosines, i, t, 1, -1.0)) <= 1e-12 * scales[1]
                    pair = zip(_trig012(product, i, t, 1.0), _trig012(cosines, i, t, 1.0), scales, strict=True)
                    for a, b, scale in pair:
                        assert abs(a - b) <= 1e-12 * scale, (scene, mu, i, t)
