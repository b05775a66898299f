"""``station teach reference|artifact NAME|sensor-mount --config FILE``: teach the cell, write the
configuration.

Reads the devices directly, as the manual tools do (the configuration's robot, camera and distance
sensor; ``--sim``: a fresh simulated station, whose arm starts at its reference pose), computes the value
(``station.teach``) and writes it into FILE with its comments kept, the old file backed up beside it.

* ``reference``: the camera over the table's artifact, the crossing in view and the camera in focus;
  the pose that centres the crossing at the working distance, the camera's orientation kept, becomes
  ``[robot] reference_joints_deg`` (the arm is left there).
* ``artifact NAME``: the crossing of artifact NAME in view (jog there first); the camera is squared to
  its plane (read by the sensor at four points around the crossing) and centred at the working
  distance; its crossing, normal and square turn go into ``[calibration]`` (in place of NAME, or added).
* ``sensor-mount``: the camera square to the table's artifact and in focus (the working distance): the
  camera moved along its optical axis over known heights, the sensor read at each; the mount's offset
  along the axis goes into ``[distance_sensor] mount``.

``--calibration FILE`` (the calibrated parameter set ``station calibrate SESSION --out FILE`` writes, as
``station robot move-camera`` takes it): teach through the calibrated arm instead of the nominal model;
after the arm's calibration, teach the artifacts again so: their normals and turns lose the arm's
orientation error (``station.teach``'s notes say in which frame they then are). The written line's
comment and ``taught.model`` say which model the value was read through.

Every motion is checked by the robot (limits, keep-out along the path, speed cap) before it is sent, at
the jog speed. Exit 0 when written, 1 when the devices or the readings refuse (nothing written), 2 for
usage errors. ``--json``: one object (``what``, ``taught``, ``config``, ``backup``, ``changes``).
"""

from __future__ import annotations

import argparse
import json
import sys

from station import config
from station.commands._parsing import SubParsers
from station.devices import DeviceError

__all__ = ["register", "run"]


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "teach",
        help="teach the reference pose, an artifact or the sensor mount into station.toml",
        description="Teach the cell from the station's own readings and write the configuration (comments"
        " kept, the old file backed up).",
    )
    p.add_argument("what", choices=("reference", "artifact", "sensor-mount"))
    p.add_argument(
        "name", nargs="?", default=None, metavar="NAME", help="the artifact's name (artifact only)"
    )
    p.add_argument("--config", required=True, metavar="FILE", help="the station configuration to teach")
    p.add_argument(
        "--calibration",
        metavar="FILE",
        help="read through this calibrated arm (station calibrate SESSION --out FILE), not the nominal model",
    )
    p.add_argument("--sim", action="store_true", help="read a fresh simulated station instead of the devices")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=lambda args: run(p, args))


def _devices(args: argparse.Namespace) -> config.StationDevices:
    if args.sim:
        return config.open_sim_station()
    return config.open_station(config.load_config(args.config))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    if (args.what == "artifact") != (args.name is not None):
        parser.error("artifact needs its NAME; reference and sensor-mount take none")
    from station.teach import TeachError, model_from_file, rig_for, taught_values, update_config

    try:
        station_config = config.load_config(args.config)  # the file to write must be valid first
    except config.ConfigurationError as exc:
        parser.error(str(exc))
    model = None
    if args.calibration is not None:
        try:  # before anything moves: a file that cannot be taught through is a usage error
            model = model_from_file(args.calibration, station_config.camera_frame("teaching").matrix())
        except TeachError as exc:
            parser.error(f"--calibration {args.calibration}: {exc}")
    devices: config.StationDevices | None = None
    try:
        devices = _devices(args)
        for device in (devices.robot, devices.camera, devices.distance_sensor):
            if device is not None:
                device.connect()
        taught, edit = taught_values(rig_for(devices, model=model), args.what, args.name)
        done = update_config(args.config, edit)
    except (DeviceError, TeachError, config.ConfigurationError, ValueError) as exc:
        print(f"station teach: {exc}; nothing was written", file=sys.stderr)
        return 1
    finally:
        if devices is not None:
            for device in (devices.distance_sensor, devices.camera, devices.robot):
                if device is not None:
                    device.close()
            devices.close_owned()
    doc = {
        "what": args.what,
        "taught": taught,
        "config": str(done.path),
        "backup": str(done.backup),
        "changes": list(done.changes),
    }
    if args.json:
        print(json.dumps(doc))
    else:
        for line in done.changes:
            print(line)
        print(f"written to {done.path} (the old file is {done.backup})")
    return 0
