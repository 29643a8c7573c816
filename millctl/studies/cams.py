"""The paper's cam claim tested: the double-acting cam against the single-acting one at the same speeds.

"A double acting cam would ensure that ... the possible number of collisions
gets doubled" (the paper, "The cam design"). For each cam speed ω_v this
compares the two cams' envelopes under one law, and — at the highest ω_r both
envelopes allow — the impacts per rod and revolution p and the share of cam
phases that detach, in both model variants (level-(b) summaries,
:func:`~millctl.physics.telemetry.revolution_summary`).
"""

from __future__ import annotations

import math
from typing import Any

from millctl.config.models import CamShape, LimitLaw, MillConfig, ModelVariant
from millctl.physics.model import MillModel
from millctl.physics.telemetry import revolution_summary
from millctl.safety import Envelope
from millctl.units import rpm_to_rad_s

CAM_PHASES = 16
"""Cam phases per summary: the detach fraction is resolved to 1/16."""


def with_cam(config: MillConfig, shape: CamShape) -> MillConfig:
    """The configuration with another cam shape."""
    cam = config.mill.cam.model_copy(update={"shape": shape})
    return config.model_copy(update={"mill": config.mill.model_copy(update={"cam": cam})})


def _model(config: MillConfig, shape: CamShape, variant: ModelVariant) -> MillModel:
    cfg = with_cam(config, shape)
    model = cfg.model.model_copy(update={"variant": variant})
    return MillModel.from_config(cfg.model_copy(update={"model": model}))


def compare_cams(config: MillConfig, law: LimitLaw, vibration_rpm: list[float]) -> list[dict[str, Any]]:
    """One row per ω_v: both cams' envelopes (rpm) and, at a speed both allow, p and the detach fraction."""
    envelopes = {shape: Envelope.from_config(with_cam(config, shape), law=law) for shape in CamShape}
    rows = []
    for w_v in vibration_rpm:
        limits = {shape: float(envelopes[shape].omega_r_limit_rpm(w_v)) for shape in CamShape}
        w_r = min(limits.values())
        row: dict[str, Any] = {
            "vibration_rpm": w_v,
            **{f"limit_rotary_{shape.value}_rpm": limits[shape] for shape in CamShape},
            "rotary_rpm": w_r,
        }
        for variant in ModelVariant:
            for shape in CamShape:
                key = f"{variant.value}_{shape.value}"
                if w_r < 1.0:
                    row[f"p_{key}"], row[f"detach_fraction_{key}"] = math.nan, math.nan
                    continue
                s = revolution_summary(
                    _model(config, shape, variant), rpm_to_rad_s(w_r), rpm_to_rad_s(w_v), cam_phases=CAM_PHASES
                )
                row[f"p_{key}"], row[f"detach_fraction_{key}"] = s.collisions_per_rod_rev, s.detach_fraction
        rows.append(row)
    return rows


__all__ = ["CAM_PHASES", "compare_cams", "with_cam"]
