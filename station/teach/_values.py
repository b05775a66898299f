"""The taught values of each thing ``station teach`` and the API's teach routes teach, as JSON, with the
edit that writes them into the station's configuration (one rule for the terminal and the service)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from station.teach._procedure import TeachRig, teach_artifact, teach_reference, teach_sensor_mount
from station.teach._writer import set_artifact, set_reference, set_sensor_mount_z

__all__ = ["taught_values"]


def taught_values(
    rig: TeachRig, what: str, name: str | None
) -> tuple[dict[str, Any], Callable[..., list[str]]]:
    """What ``station teach`` and the API's teach routes compute with ``rig`` (``what``: reference,
    artifact (``name``) or sensor-mount): the taught values as JSON (``model``: the arm model they were
    read through, ``TeachRig.model_source``; an artifact's position is always the nominal model's), and
    the edit that writes them into the configuration document (:func:`station.teach.update_config`; the
    model in the written line's comment)."""
    source = rig.model_source
    through = "the nominal arm model" if rig.model is None else rig.model.describe()
    if what == "reference":
        ref = teach_reference(rig)
        return (
            {
                "reference_joints_deg": list(ref.joints_deg),
                "crossing_mm": list(ref.crossing_mm),
                "center_px": list(ref.center_px),
                "plane_rms_mm": ref.plane_rms_mm,
                "model": source,
            },
            lambda doc: set_reference(doc, ref.joints_deg, through),
        )
    if what == "artifact":
        assert name is not None
        art = teach_artifact(rig)
        # the crossing's position is the nominal model's reading whatever the model (``teach_artifact``)
        artifact_through = through if rig.model is None else f"{through} (position: the nominal model)"
        return (
            {
                "name": name,
                "position_mm": list(art.position_mm),
                "normal": list(art.normal),
                "turn_deg": art.turn_deg,
                "joints_deg": list(art.joints_deg),
                "center_px": list(art.center_px),
                "plane_rms_mm": art.plane_rms_mm,
                "model": source,
            },
            lambda doc: set_artifact(doc, name, art.position_mm, art.normal, art.turn_deg, artifact_through),
        )
    fit, pairs = teach_sensor_mount(rig)
    return (
        {
            "translation_z_mm": fit.translation_z_mm,
            "slope": fit.slope,
            "expected_slope": fit.expected_slope,
            "rms_mm": fit.rms_mm,
            "pairs_mm": [list(p) for p in pairs],
            "model": source,
        },
        lambda doc: set_sensor_mount_z(doc, fit.translation_z_mm, through),
    )
