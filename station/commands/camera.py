"""``station camera (--sim | --v4l2 DEV | --aravis ID) grab OUT.png``: grab one frame to a file."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from station import config
from station.commands import SubParsers
from station.devices import Camera, DeviceError, ExposureAdjustable
from station.imageio import ImageFileError, write_image


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "camera",
        help="grab frames from a camera (simulated, V4L2 frame grabber, or GenICam via Aravis)",
        description="Grab a frame and write it losslessly (PNG; 16-bit frames stay 16-bit).",
    )
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--sim", action="store_true", help="the simulated flange camera")
    which.add_argument("--v4l2", metavar="DEV", help="a V4L2 frame grabber: /dev/videoN or its index")
    which.add_argument("--aravis", metavar="ID", help="a GenICam camera: Aravis device id or IP address")
    p.add_argument("--average", type=int, default=1, metavar="N", help="average N frames into one")
    p.add_argument("--exposure-us", type=float, default=None, help="set the exposure first (us)")
    p.add_argument("--timeout", type=float, default=2.0, help="seconds to wait for each frame")
    p.add_argument("--json", action="store_true", help="print the frame's metadata as JSON")
    csub = p.add_subparsers(dest="camera_command", required=True, metavar="COMMAND")
    grab = csub.add_parser("grab", help="grab one frame into OUT (PNG)")
    grab.add_argument("out", metavar="OUT.png")
    p.set_defaults(func=lambda args: run(p, args))


def _build(args: argparse.Namespace) -> Camera:
    options: dict[str, Any]
    if args.sim:
        name, options = "sim", {}
    elif args.v4l2 is not None:
        dev = args.v4l2
        name, options = "v4l2", {"device": int(dev) if dev.isdigit() else dev}
    else:
        name, options = "aravis", {"camera_id": args.aravis}
    camera: Camera = config.build("camera", name, **options)
    return camera


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    if args.average < 1:
        parser.error(f"--average must be at least 1, got {args.average}")
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
        path = write_image(args.out, frame.image)
    except (DeviceError, ImageFileError, ValueError) as exc:
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
