"""One simulated station: the arm, the camera on its flange, the X-Y table and the artifact on it.

Frames (all mm, right-handed):

* **base** ``B``: the arm's base frame (``station.kinematics``), z up; the table top is horizontal.
* **camera** ``C``: on the flange through the tool transform; OpenCV's camera axes: x right, y down in the
  image, z forward along the optical axis. At the reference pose the camera looks straight down.
* **table** ``T``: the X-Y table's carriage; its X and Y axes lie in the table plane, turned by
  ``table_rotation_deg`` about base z from the camera's image axes at the reference pose, and its Y axis
  leans ``table_skew_deg`` toward X (the seed found its axes not perpendicular). A commanded table
  position (x, y) moves the carriage by ``x * X_axis + y * Y_axis`` (signs: +x along the table's +X).
* **artifact** ``A``: origin at the groove crossing, u along the "horizontal" groove, v along the
  "vertical" one, normal pointing down into the table (so that u x v = n), matching ``sim.artifact``.
  At the reference pose and table position (0, 0), the artifact's u and v axes are the image's x and y
  turned by ``artifact_rotation_deg`` and the crossing sits on the optical axis at the working distance.

The arm is built to a true DH table (``WorldSpec.true_dh``; by default the nominal table plus errors
drawn by ``sim.kinematic_errors.perturbed_dh(WorldSpec.dh_error_seed)``; ``true_dh = A465_DH`` is a
perfect arm): everything the camera sees comes from it, while the controller twin keeps reporting its
encoders and nominal WORLD values, as a real controller does. The artifact lies flat on the table
(its normal along the base's -z) under the true camera at the reference pose.

A joint move changes where the camera is (through the true kinematics, plus the arm's Cartesian error:
``WorldSpec.flange_errors``, the structure and thermal part of ``sim.arm_errors``' model, which moves
the flange after each motion of the arm without any joint reading showing it); a micrometer turn
changes where the artifact is (through the table, with its imperfections: non-perpendicular axes,
micrometer resolution, backlash). The camera renders what it sees with ``sim.artifact.render``;
defocus grows the blur with the distance from the focal plane. The world's truth (flange pose, table
position, artifact pose, ``center_mm``) is for tests and benchmarks, never for the station's
orchestrator.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt

from sim._render_features import vignetting_map
from sim._table import TableAxis, TableImperfections
from sim._world_geometry import center_mm_of, euler_xyz, on_artifact
from sim._world_rulers import render_ruler_view, table_ruler_frame
from sim._world_spec import (
    REFERENCE_JOINTS_DEG,
    TABLE_CONTENTS,
    TableContent,
    WorldSpec,
    magnification_error,
)
from sim._world_target import render_table_target
from sim.arm_errors import FlangeErrorSequence
from sim.artifact import Pose, Truth, homography_for, render
from sim.cell_rulers import on_substrate, ray_hit, seen_ruler
from sim.kinematic_errors import perturbed_dh
from sim.lens import nominal_intrinsics, true_intrinsics
from sim.presets import NoisePreset, get_preset
from sim.ruler import RulerTruth
from sim.target import TargetTruth
from station.kinematics import DHRow, Kinematics, rot_x, rot_z, transform

__all__ = [
    "INCH_MM",
    "REFERENCE_JOINTS_DEG",
    "TABLE_CONTENTS",
    "TableContent",
    "TableImperfections",
    "World",
    "WorldSpec",
    "euler_xyz",
    "magnification_error",
]

FloatArray = npt.NDArray[np.float64]
INCH_MM = 25.4


class World:
    """The simulated station's shared state. Thread-safe: the twins read and change it concurrently.

    Parameters
    ----------
    spec
        The station's geometry and optics.
    joints
        Where the arm really is, deg: a callable (e.g. a controller twin's attained joints); by default
        the arm stays at the reference pose.
    moves
        How many motions the arm has started: the flange's Cartesian error (``spec.flange_errors``)
        takes a new value with each. By default, when ``joints`` is a method of an object with a
        ``moves`` counter (the twin's arm: ``joints=twin.arm.actual_exact``), that counter; else each
        new joint reading counts as a motion.
    seed
        Seeds the flange's Cartesian error (deterministic per seed).
    """

    def __init__(
        self,
        spec: WorldSpec | None = None,
        *,
        joints: Callable[[], npt.ArrayLike] | None = None,
        moves: Callable[[], int] | None = None,
        seed: int = 0,
    ) -> None:
        self.spec = spec or WorldSpec()
        self._lock = threading.Lock()
        self._joints: Callable[[], npt.ArrayLike] = joints or (lambda: self.spec.reference_joints_deg)
        owner: Any = getattr(joints, "__self__", None)
        if moves is None and isinstance(getattr(owner, "moves", None), int):

            def moves() -> int:  # the twin's arm counts its motions
                return int(owner.moves)

        self._moves = moves
        self._seen_joints: FloatArray | None = None
        self._seen_moves = 0
        self._last_frame_homography: FloatArray | None = None
        self.flange_errors = FlangeErrorSequence(self.spec.flange_errors, seed)
        tool = transform(np.eye(3), (0.0, 0.0, self.spec.tool_length_mm))
        self.true_dh: tuple[DHRow, ...] = (
            tuple(self.spec.true_dh)
            if self.spec.true_dh is not None
            else perturbed_dh(self.spec.dh_error_seed)
        )
        self.kinematics = Kinematics(self.true_dh, tool=tool)
        """The arm's true kinematics (camera as the tool): truth, for tests and benchmarks."""
        lens_seed = self.spec.magnification_seed
        lens, camera = self.spec.true_intrinsics_seed, self.spec.camera
        seeded = None if lens is None else true_intrinsics(lens, camera)
        if lens_seed is not None:
            self.magnification_error = magnification_error(lens_seed, self.spec.magnification_range)
        elif seeded is not None:  # one lens: the artifact is seen at the true focal length's scale
            K = seeded.camera_matrix
            self.magnification_error = float(K[0, 0] + K[1, 1]) / (2.0 * camera.focal_px) - 1.0
        else:
            self.magnification_error = 0.0
        """The camera's true magnification over its nominal, minus 1: truth."""
        self.true_camera = replace(
            self.spec.camera, px_per_mm=self.spec.camera.px_per_mm * (1.0 + self.magnification_error)
        )
        """The camera as it really is (its focal length; the focal plane stays at the working distance):
        what the world renders with. The station is told ``spec.camera``."""
        self.true_intrinsics = nominal_intrinsics(self.true_camera) if seeded is None else seeded
        """The camera's true intrinsics the calibration target is rendered with: truth."""
        self.last_target: TargetTruth | None = None
        """The calibration target's truth in the last frame rendered (None: no target in it): truth."""
        res_mm = self.spec.table.resolution_in * INCH_MM
        self._x = TableAxis(res_mm, self.spec.table.backlash_mm)
        self._y = TableAxis(res_mm, self.spec.table.backlash_mm)
        self._preset: NoisePreset = get_preset(self.spec.preset)
        # Where the table and artifact sit: chosen so that at the reference pose and table (0, 0) the
        # crossing is on the optical axis, in focus, turned by artifact_rotation_deg in the image.
        cam0 = self.camera_pose_at(self.spec.reference_joints_deg)
        focus = cam0[:3, :3] @ np.array([0.0, 0.0, self.spec.camera.working_distance_mm]) + cam0[:3, 3]
        # The table is level: its frame has z down (as the camera's at the reference pose, nearly) and x
        # along the camera's x projected on the horizontal. Artifact axes: u, v in the table plane, n = down.
        z_h = np.array([0.0, 0.0, -1.0])
        x_cam = cam0[:3, 0]
        x_h = x_cam - (x_cam @ z_h) * z_h
        x_h /= np.linalg.norm(x_h)
        level = np.column_stack([x_h, np.cross(z_h, x_h), z_h])
        R_art = level @ rot_z(math.radians(self.spec.artifact_rotation_deg))
        self._artifact0 = transform(R_art, focus)
        turn = rot_z(math.radians(self.spec.table_rotation_deg))
        x_axis = level @ turn @ np.array([1.0, 0.0, 0.0])
        skew = math.radians(self.spec.table.skew_deg)
        y_dir = turn @ np.array([math.sin(skew), math.cos(skew), 0.0])
        y_axis = level @ y_dir
        self._table_axes = np.column_stack([x_axis, y_axis])  # base frame, 3x2
        flat = np.diag([1.0, -1.0, -1.0])  # u along base x, normal down (u x v = n)
        self._bench = [
            transform(rot_z(math.radians(yaw)) @ rot_x(math.radians(tilt)) @ flat, (x, y, z))
            for x, y, z, yaw, tilt in self.spec.bench_artifacts
        ]
        self._rulers = [mount.frame(float(focus[2])) for mount in self.spec.rulers]  # on the table's plane
        self._table_content: TableContent = (
            "target" if self.spec.calibration_target else self.spec.table_artifact
        )
        self._table_ruler = table_ruler_frame(self._artifact0) if self._table_content == "ruler" else None
        self._last_ruler: tuple[int, RulerTruth] | None = None

    # ------------------------------------------------------------------ arm and camera

    def joints_deg(self) -> FloatArray:
        return np.asarray(self._joints(), dtype=np.float64)

    def camera_pose_at(self, joints_deg: Sequence[float], *, move: int | None = None) -> FloatArray:
        """4x4 camera frame in the base frame for the given joints.

        ``move``: add the flange's Cartesian error after that many motions (None: the kinematics alone).
        """
        pose = self.kinematics.forward(joints_deg, tool=True)
        if move is not None and self.spec.flange_errors.enabled:
            pose[:3, 3] += self.flange_errors.at(move)
        return pose

    def moves(self) -> int:
        """Motions of the arm so far (what indexes the flange's Cartesian error)."""
        if self._moves is not None:
            return int(self._moves())
        q = self.joints_deg()
        with self._lock:
            if self._seen_joints is not None and not np.array_equal(q, self._seen_joints):
                self._seen_moves += 1
            self._seen_joints = q
            return self._seen_moves

    def camera_pose(self) -> FloatArray:
        """Where the camera really is now: the attained joints and the flange's Cartesian error."""
        move = self.moves()
        return self.camera_pose_at(tuple(self.joints_deg()), move=move)

    # ------------------------------------------------------------------ table and artifact

    def set_table_readings(self, x_mm: float, y_mm: float) -> None:
        """What the operator does: turn the micrometers to these readings (mm)."""
        with self._lock:
            self._x.set_reading(x_mm)
            self._y.set_reading(y_mm)

    def table_readings_mm(self) -> tuple[float, float]:
        with self._lock:
            return self._x.reading_mm, self._y.reading_mm

    def table_position_mm(self) -> tuple[float, float]:
        """Where the carriage really is along its two axes (mm): truth, for tests."""
        with self._lock:
            return self._x.position_mm, self._y.position_mm

    @property
    def table_content(self) -> TableContent:
        """What lies on the X-Y table now: the crossed artifact, a ruler or the calibration target."""
        with self._lock:
            return self._table_content

    def place_on_table(self, content: TableContent) -> None:
        """What the operator does: take what lies on the X-Y table off and put ``content`` there.

        Whatever it is lies where the carriage carries the artifact (its frame is the table artifact's,
        :meth:`table_artifact_pose`, which moves with the micrometers): the next frame renders it, the
        distance sensor's beam reads its surface (a ruler's glass; the target and the cross lie in the
        table artifact's plane)."""
        if content not in TABLE_CONTENTS:
            raise ValueError(f"the X-Y table takes one of {', '.join(TABLE_CONTENTS)}, got {content!r}")
        with self._lock:
            self._table_content = content
            self._table_ruler = table_ruler_frame(self._artifact0) if content == "ruler" else None
            self._last_frame_homography, self._last_ruler = None, None
            if content != "target":
                self.last_target = None

    def table_artifact_pose(self) -> FloatArray:
        """4x4 frame of the artifact on the table, in the base frame: truth, for tests."""
        tx, ty = self.table_position_mm()
        T = self._artifact0.copy()
        T[:3, 3] += self._table_axes @ np.array([tx, ty])
        return T

    def artifact_poses(self) -> list[FloatArray]:
        """Every artifact's 4x4 frame in the base frame: the table's first, then the bench's (truth)."""
        return [self.table_artifact_pose(), *(T.copy() for T in self._bench)]

    def ruler_poses(self) -> list[FloatArray]:
        """Each ruler's 4x4 frame in the base frame (``sim.cell_rulers``; truth); the table's last, where
        the table carries one (it moves with the carriage)."""
        with self._lock:
            table_ruler = self._table_ruler
        if table_ruler is None:
            return [F.copy() for F in self._rulers]
        F = table_ruler.copy()
        F[:3, 3] += self._table_axes @ np.array(self.table_position_mm())
        return [*(R.copy() for R in self._rulers), F]

    def seen_ruler(self, camera_pose: FloatArray) -> int | None:
        """Index (in :meth:`ruler_poses`) of the ruler whose glass the optical axis meets, or None."""
        return seen_ruler(camera_pose, self.ruler_poses())

    def surface_pose(self, head_pose: FloatArray) -> FloatArray:
        """What a beam from ``head_pose`` (4x4, along its +z) reads: a ruler's glass where the beam meets
        one, as a plate frame centred where it meets it (normal into the glass), else the artifact the
        camera sees (:meth:`artifact_pose`). Truth, for the distance sensor's twin."""
        for F in self.ruler_poses():
            hit = ray_hit(head_pose[:3, 3], head_pose[:3, 2], F)
            if hit is not None and on_substrate(hit[0], hit[1]):
                return transform(F[:3, :3], F[:3, :3] @ np.array([hit[0], hit[1], 0.0]) + F[:3, 3])
        return self.artifact_pose()

    def seen_artifact(self, camera_pose: FloatArray) -> int:
        """Index (in :meth:`artifact_poses`) of the artifact nearest the optical axis of a camera pose."""
        poses = self.artifact_poses()
        if len(poses) == 1:
            return 0
        best, best_d = 0, math.inf
        for i, T in enumerate(poses):
            p = np.linalg.solve(camera_pose, np.append(T[:3, 3], 1.0))[:3]
            if p[2] <= 0:  # behind the camera
                continue
            d = math.hypot(p[0], p[1])
            if d < best_d:
                best, best_d = i, d
        return best

    def artifact_pose(self, index: int | None = None) -> FloatArray:
        """4x4 artifact frame in the base frame (truth, for tests): the one the camera sees now (the
        table's unless bench artifacts are configured), or ``artifact_poses()[index]``."""
        poses = self.artifact_poses()
        if index is None:
            index = self.seen_artifact(self.camera_pose()) if len(poses) > 1 else 0
        return poses[index]

    def artifact_in_camera(self) -> FloatArray:
        """4x4 frame, in the camera frame, of the artifact the camera sees."""
        cam = self.camera_pose()
        return np.linalg.inv(cam) @ self.artifact_poses()[self.seen_artifact(cam)]

    def pose(self, artifact_in_camera: FloatArray | None = None) -> Pose:
        """The artifact's pose as the renderer takes it (now, or for the given 4x4 artifact-in-camera)."""
        T = self.artifact_in_camera() if artifact_in_camera is None else artifact_in_camera
        a, b, c = euler_xyz(T[:3, :3])
        wd = self.spec.camera.working_distance_mm
        return Pose(
            float(T[0, 3]),
            float(T[1, 3]),
            rotation_deg=c,
            tilt_x_deg=a,
            tilt_y_deg=b,
            z_mm=float(T[2, 3]) - wd,
        )

    @property
    def principal_point_px(self) -> tuple[float, float]:
        """The image of the optical axis: the image centre (the sim camera is an ideal pinhole)."""
        return (self.spec.camera.width - 1) / 2.0, (self.spec.camera.height - 1) / 2.0

    def _relative_px(self, tool_point: bool) -> tuple[float, float]:
        return self.principal_point_px if tool_point else (0.0, 0.0)

    def center_mm_at(
        self, joints_deg: Sequence[float], *, move: int | None = None, tool_point: bool = False
    ) -> tuple[float, float]:
        """The true position the station measures with the arm at ``joints_deg`` (truth, for tests), mm.

        The crossing relative to the image's origin pixel, in the artifact's axes: ``center_mm`` as
        ``station.vision.measure`` defines it; with ``tool_point``, relative to where the optical axis
        meets the artifact (the repeatability plan's position: a turn about the optical axis does not
        move it). With the table where it is now and, when ``move`` is given, the flange's Cartesian error
        after that many motions (``moves()`` at the capture).
        """
        cam = self.camera_pose_at(joints_deg, move=move)
        T = np.linalg.inv(cam) @ self.artifact_poses()[self.seen_artifact(cam)]
        return center_mm_of(homography_for(self.pose(T), self.true_camera), self._relative_px(tool_point))

    def center_mm(self, *, tool_point: bool = False) -> tuple[float, float]:
        """The true position now (see :meth:`center_mm_at`).

        The arm may still be settling: for the truth of a captured frame use :meth:`last_frame_center_mm`.
        """
        move = self.moves()
        return self.center_mm_at(tuple(self.joints_deg()), move=move, tool_point=tool_point)

    def last_frame_ruler(self) -> tuple[int, RulerTruth] | None:
        """The ruler (index in :meth:`ruler_poses`) and its truth in the last frame rendered; None before
        the first frame and when the last frame saw no ruler."""
        with self._lock:
            return self._last_ruler

    def last_frame_center_mm(self, *, tool_point: bool = False) -> tuple[float, float] | None:
        """The true position (see :meth:`center_mm_at`) in the last frame rendered: a capture's truth.

        None before the first frame, and when the last frame saw no artifact.
        """
        with self._lock:
            H = self._last_frame_homography
        return None if H is None else center_mm_of(H, self._relative_px(tool_point))

    # ------------------------------------------------------------------ imaging

    def preset_for(self, pose: Pose, *, exposure: float = 1.0) -> NoisePreset:
        """The noise preset with defocus blur for this pose and the signal scaled by ``exposure``."""
        p = self._preset
        blur = math.hypot(p.blur_sigma_px, self.spec.defocus_px_per_mm * pose.z_mm)
        return replace(
            p,
            blur_sigma_px=blur,
            land_level_dn=min(p.land_level_dn * exposure, 255.0),
            paint_level_dn=min(p.paint_level_dn * exposure, 254.0),
        )

    def render(
        self, rng: np.random.Generator, *, exposure: float = 1.0
    ) -> tuple[npt.NDArray[np.uint8], Truth | None]:
        """What the camera sees now, with the truth of that frame: a frame at every pose, as a camera gives.

        A ruler where the optical axis meets its glass (truth ``None`` for a crossing; the ruler's in
        :meth:`last_frame_ruler`); else the artifact nearest the optical axis where its plate is in view
        (what lies beyond the plate replaced by the background); the background alone, with truth
        ``None``, where no plate is in view or the one seen faces away from the camera or at a grazing
        angle (tilted 45 deg or more, beyond the renderer's model; its image would be out of focus over
        most of the field anyway). All through the true camera (:attr:`true_camera`).
        """
        cam = self.camera_pose()
        rulers = self.ruler_poses()
        r = seen_ruler(cam, rulers)
        if r is not None:
            seen_r = render_ruler_view(
                np.linalg.inv(cam) @ rulers[r],
                camera=self.true_camera,
                preset_for=lambda pose: self.preset_for(pose, exposure=exposure),
                background=lambda: self._background(rng, exposure),
                texture_seed=r,
                rng=rng,
            )
            if seen_r is not None:
                with self._lock:
                    self._last_frame_homography = None
                    self._last_ruler = (r, seen_r[1])
                return seen_r[0], None
        index = self.seen_artifact(cam)
        content = self.table_content
        if index == 0 and content == "target":
            return self._render_target(cam, rng, exposure), None
        seen = np.linalg.inv(cam) @ self.artifact_poses()[index]
        # a ruler on the table took the cross's place: beyond its glass lies the table top
        view = None if index == 0 and content == "ruler" else self._view(seen)
        if view is None:
            with self._lock:
                self._last_frame_homography = None
                self._last_ruler = None
            return self._background(rng, exposure), None
        pose, outside = view
        image, truth = render(
            pose,
            preset=self.preset_for(pose, exposure=exposure),
            artifact=self.spec.artifact,
            camera=self.true_camera,
            rng=rng,
        )
        if outside is not None:
            image = np.where(outside, self._background(rng, exposure), image)
        with self._lock:
            self._last_frame_homography = np.array(truth.homography)
            self._last_ruler = None
        return image, truth

    def _render_target(
        self, cam: FloatArray, rng: np.random.Generator, exposure: float
    ) -> npt.NDArray[np.uint8]:
        """A frame of the calibration target on the table (the background where it is not in view)."""
        seen = render_table_target(
            cam, self.table_artifact_pose(), self.spec, self.true_intrinsics, rng, exposure
        )
        with self._lock:
            self._last_frame_homography, self._last_ruler = None, None
            self.last_target = None if seen is None else seen[1]
        return self._background(rng, exposure) if seen is None else seen[0]

    def _view(self, artifact_in_camera: FloatArray) -> tuple[Pose, npt.NDArray[np.bool_] | None] | None:
        """The renderer's pose of an artifact (4x4 in the camera frame) and the pixels outside its plate
        (``None``: the whole frame is on it), or ``None`` when no part of its plate is in view."""
        T = artifact_in_camera
        a, b, _ = euler_xyz(T[:3, :3])
        if abs(a) >= 45.0 or abs(b) >= 45.0 or T[2, 3] <= 1.0:  # grazing, facing away, or at the lens
            return None
        pose = self.pose(T)
        cam = self.spec.camera
        corners = np.array([[0, 0], [cam.width - 1, 0], [0, cam.height - 1], [cam.width - 1, cam.height - 1]])
        H_inv = np.asarray(np.linalg.inv(homography_for(pose, self.true_camera)), dtype=np.float64)
        half = self.spec.artifact_half_size_mm
        seen = on_artifact(H_inv, corners.astype(np.float64))
        if np.all(np.abs(seen) <= half):
            return pose, None  # the footprint of the frame is convex: all of it is on the plate
        if np.any(np.all(seen > half, axis=0)) or np.any(np.all(seen < -half, axis=0)):
            return None  # the whole footprint beyond one side of the plate
        ys, xs = np.mgrid[0 : cam.height, 0 : cam.width]
        uv = on_artifact(H_inv, np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float64))
        outside = np.any(np.abs(uv) > half, axis=1).reshape(cam.height, cam.width)
        return None if bool(np.all(outside)) else (pose, outside)

    def _background(self, rng: np.random.Generator, exposure: float) -> npt.NDArray[np.uint8]:
        """A frame of the background: a uniform level under the preset's vignetting and noise."""
        p = self._preset
        shape = self.spec.camera.shape
        level = np.float32(min(self.spec.background_dn * exposure, 255.0))
        clean = level * vignetting_map(shape, p.vignetting)
        variance = np.float32(p.read_noise_dn**2) + np.float32(p.shot_noise_gain_dn_per_e) * clean
        noisy = clean + np.sqrt(variance) * rng.standard_normal(shape, dtype=np.float32)
        return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
