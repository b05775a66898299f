"""Choosing the backend: ``--cluster``, ``[compute]`` and the service accept and refuse the same values,
with errors that say what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from station.batch import max_jobs
from station.cli import main
from station.compute import ComputeSpec, DaskBackend, LocalBackend, open_backend, parse_cluster
from station.config import ConfigurationError, load_config


@pytest.mark.parametrize(
    ("text", "normalised"),
    [
        ("local", "local"),
        (" LOCAL ", "local"),
        ("local:2", "local:2"),
        ("local:02", "local:2"),
        ("tcp://10.0.0.5:8786", "tcp://10.0.0.5:8786"),
        ("10.0.0.5", "tcp://10.0.0.5:8786"),
        ("sched.lab:9000", "tcp://sched.lab:9000"),
        ("tls://sched.lab:8786", "tls://sched.lab:8786"),
        ("[::1]:8786", "tcp://[::1]:8786"),
    ],
)
def test_accepted_clusters_are_normalised(text: str, normalised: str) -> None:
    assert parse_cluster(text) == normalised


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("local:0", "local:N needs N from 1 to"),
        (f"local:{max_jobs() + 1}", "local:N needs N from 1 to"),
        ("local:two", "local:N needs N from 1 to"),
        ("http://sched.lab:8786", "scheme 'http' is not one of tcp, tls"),
        ("tcp://sched.lab:99999", "not an address"),
        ("tcp://", "expected local"),
        ("tcp://sched.lab:8786/status", "expected local"),
        ("tcp://me@sched.lab:8786", "expected local"),
    ],
)
def test_refused_clusters_say_what_is_allowed(text: str, message: str) -> None:
    with pytest.raises(ValueError, match="cluster") as exc:
        parse_cluster(text)
    assert message in str(exc.value)


def test_ship_images_needs_a_cluster() -> None:
    with pytest.raises(ValueError, match="--cluster ADDRESS or local:N"):
        ComputeSpec(ship_images=True)
    assert ComputeSpec.of("local:1", ship_images=True).local_workers == 1


def test_the_default_is_the_local_pool_which_starts_nothing() -> None:
    backend = open_backend(ComputeSpec(jobs=2))
    assert isinstance(backend, LocalBackend)
    assert backend.jobs == 2
    cluster = open_backend(ComputeSpec.of("tcp://127.0.0.1:8786"))
    assert isinstance(cluster, DaskBackend)
    cluster.close()  # never connected: nothing to close, no error


BASE = """
name = "a465-lab-1"

[camera]
driver = "v4l2"
options = { device = "/dev/video9" }
"""


def test_the_configuration_names_the_cluster(tmp_path: Path) -> None:
    path = tmp_path / "station.toml"
    path.write_text(BASE, encoding="utf-8")
    assert load_config(path).compute.spec(jobs=3) == ComputeSpec("local", 3, False)
    path.write_text(BASE + '\n[compute]\ncluster = "sched.lab"\nship_images = true\n', encoding="utf-8")
    assert load_config(path).compute.spec() == ComputeSpec("tcp://sched.lab:8786", 1, True)


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ('cluster = "local:0"', "compute.cluster"),
        ('cluster = "udp://x:1"', "scheme 'udp'"),
        ("ship_images = true", "name a cluster too"),
        ('clusters = "local"', "compute.clusters"),
    ],
)
def test_a_bad_compute_section_names_the_field(tmp_path: Path, section: str, message: str) -> None:
    path = tmp_path / "station.toml"
    path.write_text(BASE + f"\n[compute]\n{section}\n", encoding="utf-8")
    with pytest.raises(ConfigurationError, match=r"station\.toml") as exc:
        load_config(path)
    assert message in str(exc.value)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["measure", "--cluster", "local:0", "x.png"], "local:N needs N from 1 to"),
        (["measure", "--cluster", "ftp://h:1", "x.png"], "scheme 'ftp'"),
        (["measure", "--ship-images", "x.png"], "give --cluster too"),
        (["measure", "--cluster", "tcp://h:1", "--jobs", "2", "x.png"], "drop --jobs or --cluster"),
        (["run", "reanalyse", "--param", "session=abcd", "--cluster", "local:x"], "local:N needs N"),
        (["run", "reanalyse", "--param", "session=abcd", "--ship-images"], "give --cluster too"),
        (["run", "reanalyse", "--param", "session=abcd", "--jobs", "0"], "--jobs must be from 1"),
    ],
)
def test_usage_errors_exit_2_before_anything_is_measured(
    capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    captured = capsys.readouterr()
    assert message in captured.err
    assert captured.out == ""
