"""``station camera (--sim | --v4l2 DEV | --aravis ID | --config FILE) grab OUT.png``: grab one frame to a
file; with ``--config`` the camera is the configuration's ``[camera]`` (driver and options), and its
camera model, when it says the image size it holds for, must match the frames (else exit 1, saying
what to do)."""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from typing import Any

from station import config
from station.camera_model import check_image_size, read_camera_model
from station.commands._common import bounded_int, finite_float
from station.commands._parsing import SubParsers
from station.devices import Camera, DeviceError, ExposureAdjustable
from station.imageio import ImageFileError, check_output_path, write_image

#: Most frames ``--average`` may average (a thousand 640x480 frames already take a while).
MAX_AVERAGE = 1000


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "camera",
        help="grab frames from a camera (simulated, V4L2 frame grabber, or GenICam via Aravis)",
        description="Grab a frame and write it losslessly (PNG; 16-bit frames stay 16-bit).",
    )
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--config", metavar="FILE", help="the station configuration's [camera]")
    which.add_argument("--sim", action="store_true", help="the simulated flange camera")
    which.add_argument("--v4l2", metavar="DEV", help="a V4L2 frame grabber: /dev/videoN or its index")
    which.add_argument("--aravis", metavar="ID", help="a GenICam camera: Aravis device id or IP address")
    p.add_argument(
        "--average",
        type=bounded_int("--average", 1, MAX_AVERAGE),
        default=1,
        metavar="N",
        help=f"average N frames into one (1 to {MAX_AVERAGE})",
    )
    p.add_argument(
        "--exposure-us",
        type=finite_float("--exposure-us", positive=True),
        default=None,
        help="set the exposure first (us)",
    )
    p.add_argument(
        "--timeout",
        type=finite_float("--timeout", positive=True),
        default=2.0,
        help="seconds to wait for each frame",
    )
    p.add_argument("--json", action="store_true", help="print the frame's metadata as JSON")
    csub = p.add_subparsers(dest="camera_command", required=True, metavar="COMMAND")
    grab = csub.add_parser("grab", help="grab one frame into OUT (PNG or TIFF: lossless)")
    grab.add_argument(
        "out", metavar="OUT.png", help="output file: .png, .tif or .tiff, in an existing directory"
    )
    p.set_defaults(func=lambda args: run(p, args))


def _build(args: argparse.Namespace) -> Camera:
    options: dict[str, Any]
    if args.config is not None:
        station = config.load_config(args.config)
        args.camera_model = station.camera.camera_model
        camera_from_config: Camera = config.build("camera", station.camera.driver, **station.camera.options)
        return camera_from_config
    args.camera_model = None
    if args.sim:
        name, options = "sim", {}
    elif args.v4l2 is not None:
        dev = args.v4l2
        name, options = "v4l2", {"device": int(dev) if dev.isdigit() else dev}
    else:
        name, options = "aravis", {"camera_id": args.aravis}
    camera: Camera = config.build("camera", name, **options)
    return camera


def _keep(image: Any, exc: ImageFileError) -> str:
    """Save a grabbed frame that could not be written where asked, so that nothing captured is lost."""
    try:
        fd, spare = tempfile.mkstemp(prefix="station-grab-", suffix=".png")
        os.close(fd)
        write_image(spare, image)
    except (OSError, ImageFileError) as again:
        return f"{exc}; the frame is lost (it could not be kept in the temporary directory either: {again})"
    return f"{exc}; the frame was kept in {spare}"


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    try:  # before anything is grabbed: a frame must never be taken only to be lost
        check_output_path(args.out)
    except ImageFileError as exc:
        parser.error(str(exc))
    camera: Camera | None = None
    try:
        camera = _build(args)
        camera.connect()
        if args.exposure_us is not None:
            if not isinstance(camera, ExposureAdjustable):
                raise DeviceError("this camera has no exposure setting")
            camera.set_exposure_us(args.exposure_us)
        frames = camera.grab_many(args.average, average=args.average > 1, timeout_s=args.timeout)
        frame = frames[0]
        try:
            path = write_image(args.out, frame.image)
        except ImageFileError as exc:
            print(f"station camera: {_keep(frame.image, exc)}", file=sys.stderr)
            return 1
        if args.camera_model is not None:  # the configuration's model must hold for these frames
            height, width = frame.image.shape[:2]
            try:
                check_image_size(read_camera_model(args.camera_model), width, height, require_size=False)
            except ValueError as exc:
                print(f"station camera: the frame is in {path}, but {exc}", file=sys.stderr)
                return 1
    except (DeviceError, ImageFileError, ValueError, config.ConfigurationError) as exc:
        print(f"station camera: {exc}", file=sys.stderr)
        return 1
    finally:
        if camera is not None:
            camera.close()
    h, w = frame.image.shape[:2]
    info = {
        "file": str(path),
        "width": w,
        "height": h,
        "dtype": str(frame.image.dtype),
        "frame_id": frame.frame_id,
        "averaged": frame.averaged,
        "timestamp_s": frame.timestamp_s,
    }
    print(json.dumps(info) if args.json else f"{path}: {w}x{h} {frame.image.dtype}, frame {frame.frame_id}")
    return 0
