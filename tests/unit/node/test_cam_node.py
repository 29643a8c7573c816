"""The node with a double-acting cam: its interlock and its physics telemetry use the cam's lift."""

from __future__ import annotations

from collections.abc import Callable

from millctl.config import CamShape, LimitLaw, MillConfig
from millctl.protocol import PhysicsTelemetry, RefusalCode, Setpoints
from millctl.studies.cams import with_cam

from .conftest import Bench


def _corrected_every_phase(config: MillConfig, shape: CamShape) -> MillConfig:
    cfg = with_cam(config, shape)
    interlock = cfg.interlock.model_copy(update={"law": LimitLaw.CORRECTED_EVERY_PHASE})
    return cfg.model_copy(update={"interlock": interlock})


def test_double_cam_node_refuses_what_the_single_cam_node_allows(
    make_bench: Callable[..., Bench], config: MillConfig
) -> None:
    single: Bench = make_bench(_corrected_every_phase(config, CamShape.SINGLE))
    double: Bench = make_bench(_corrected_every_phase(config, CamShape.DOUBLE))
    # at ω_v = 400 rpm the corrected every-phase limit is ≈ 202 rpm with the circular cam and ≈ 119 rpm with
    # the elliptical one (its lift runs at 800 rpm)
    limit_double = float(double.envelope.omega_r_limit_rpm(400.0))
    assert limit_double + 2.0 < float(single.envelope.omega_r_limit_rpm(400.0))
    target = Setpoints(round(limit_double + 2.0, 1), 400.0, 25.0, False)
    for bench in (single, double):
        bench.run_at(limit_double - 2.0, 400.0)
        assert bench.node.refused_setpoints == 0
        bench.send(target)
        bench.step(bench.tick_s)
    assert single.node.refused_setpoints == 0
    assert double.node.refused_setpoints == 1 and double.node.last_refusal is RefusalCode.ENVELOPE


def test_double_cam_node_reports_the_lift_physics(make_bench: Callable[..., Bench], config: MillConfig) -> None:
    bench: Bench = make_bench(with_cam(config, CamShape.DOUBLE), physics_worker="inline")
    reference: Bench = make_bench(config, physics_worker="inline")
    assert bench.node.physics.model.cam is CamShape.DOUBLE
    frame = bench.node.physics.frame(bench.codec, 100.0, 300.0)
    same = reference.node.physics.frame(reference.codec, 100.0, 600.0)
    assert isinstance(frame, PhysicsTelemetry) and frame == same
