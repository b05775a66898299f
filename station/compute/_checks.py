"""What every worker must have before it measures for the station, checked where it runs.

* **The data directory at the same path**: for each directory of the frames, one file of it (the
  sample) must be readable there with the size the client sees. A worker that has not mounted the
  lab's share sees an empty mount point or nothing: it is refused by name, never left to call every
  frame a missing file.
* **The same measuring software**: results must be bit-identical wherever they are computed (the
  record's promise), so the station's version, Python, numpy, OpenCV, SciPy and the vision kernels in
  use (compiled or numpy) must match the client's.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Mapping

#: directory -> (a file in it, that file's size in bytes as the client sees it)
Samples = Mapping[str, tuple[str, int]]


def fingerprint() -> dict[str, str]:
    """What the measurement's numbers depend on, in this process."""
    import cv2
    import numpy
    import scipy

    from station import __version__
    from station.vision import _kernels

    return {
        "station": __version__,
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "opencv": cv2.__version__,
        "scipy": scipy.__version__,
        "kernels": "compiled" if _kernels.compiled() is not None else "numpy",
    }


def unreadable(samples: Samples) -> list[str]:
    """Each sample this machine cannot read as the client does, with the reason."""
    problems = []
    for directory, (path, size) in sorted(samples.items()):
        try:
            seen = os.stat(path).st_size
            with open(path, "rb") as f:
                f.read(1)
        except OSError as exc:
            reason = exc.strerror or type(exc).__name__
            where = directory if not os.path.isdir(directory) else path
            problems.append(f"cannot read {where}: {reason}")
            continue
        if seen != size:
            problems.append(
                f"sees {path} with {seen} bytes where the station sees {size}: not the same files"
            )
    return problems


def probe(samples: Samples) -> dict[str, object]:
    """A worker's report: the samples it cannot read and its software."""
    return {"unreadable": unreadable(samples), "software": fingerprint()}


def software_differences(mine: Mapping[str, str], theirs: Mapping[str, str]) -> list[str]:
    """``name X here, Y there`` for each item of the fingerprint that differs."""
    return [
        f"{k} {theirs.get(k, 'missing')} where the station has {v}"
        for k, v in mine.items()
        if theirs.get(k) != v
    ]
