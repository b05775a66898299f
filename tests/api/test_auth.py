"""Access control: every route with the station's data needs the token, as mutations do; a cookie
request must come from the station's own page; only allowed Host names are served."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import httpx
import pytest

from tests.api.conftest import TOKEN, Served, ServeFactory, wait_final

SHORT = {"kind": "repeatability", "params": {"cycles": 3, "joints": [1], "warmup_cycles": 0}}
SID = "abcdef123456"
#: Every route that returns the station's data (issue 18, row 8).
READS = (
    "/api/v1/station",
    "/api/v1/sessions",
    f"/api/v1/sessions/{SID}",
    f"/api/v1/sessions/{SID}/results",
    f"/api/v1/sessions/{SID}/figures",
    f"/api/v1/sessions/{SID}/figures/a.png",
    f"/api/v1/sessions/{SID}/report.html",
    f"/api/v1/sessions/{SID}/export.zip",
    f"/api/v1/sessions/{SID}/latest.png",
    "/api/v1/camera/snapshot.png",
    "/api/v1/prompt",
    "/api/v1/events",
    f"/api/v1/sessions/{SID}/events",
)


@pytest.fixture
def offline(make_served: ServeFactory) -> Served:
    """The service without a station (no devices): enough for what is checked before a route runs."""
    return make_served(sim=False)


def test_health_and_the_page_need_no_token(offline: Served) -> None:
    served = offline
    with served.client(token=False) as c:
        r = c.get("/api/v1/health")
        assert r.status_code == 200
        assert r.json()["status"] == "ok"
        page = c.get("/")
        assert page.status_code == 200
        assert "text/html" in page.headers["content-type"]
        assert c.get("/api/v1/openapi.json").status_code == 200


def test_unauthenticated_mutations_are_refused_with_problem_details(served: Served) -> None:
    with served.client(token=False) as c:
        for method, path, body in (
            ("POST", "/api/v1/sessions", SHORT),
            ("POST", f"/api/v1/sessions/{SID}/actions", {"action": "abort"}),
            ("POST", "/api/v1/prompt/x/confirm", {}),
            ("POST", "/api/v1/prompt/x/cancel", {}),
            ("POST", "/api/v1/measure", None),
            ("POST", "/api/v1/sessions/import", None),
        ):
            r = c.request(method, path, json=body)
            assert r.status_code == 401, (method, path, r.text)
            assert r.headers["content-type"] == "application/problem+json"
            assert r.json()["code"] == "token_required"
            assert r.headers["www-authenticate"].startswith("Bearer")
    with served.client() as c:
        assert c.get("/api/v1/sessions").json()["total"] == 0  # nothing was created


def test_every_read_of_the_stations_data_needs_the_token(served: Served) -> None:
    """Row 8: reads were open on loopback, so a page that rebinds a name to 127.0.0.1 read them all."""
    with served.client(token=False) as c:
        for path in READS:
            r = c.get(path)
            assert r.status_code == 401, (path, r.status_code, r.text[:200])
            assert r.json()["code"] == "token_required"
    with served.client(token=False, headers={"Authorization": "Bearer not-the-token-at-all"}) as c:
        assert c.get("/api/v1/station").json()["code"] == "bad_token"
    with served.client() as c:
        assert c.get("/api/v1/station").status_code == 200
        assert c.get("/api/v1/sessions").status_code == 200
        assert c.get("/api/v1/prompt").status_code == 204


@pytest.mark.parametrize("host", ["attacker.example:18465", "attacker.example", "127.0.0.1.nip.io", ""])
def test_a_host_name_that_is_not_allowed_is_refused_before_routing(offline: Served, host: str) -> None:
    """Row 8, DNS rebinding: a foreign Host is 400, with or without the token, on every path."""
    served = offline
    for token in (False, True):
        with served.client(token=token, headers={"Host": host}) as c:
            for path in ("/api/v1/station", "/api/v1/camera/snapshot.png", "/api/v1/health", "/", "/nowhere"):
                r = c.get(path)
                assert r.status_code == 400, (host, path, r.status_code)
                assert r.headers["content-type"] == "application/problem+json"
                assert r.json()["code"] == "bad_host"
                assert "--allowed-host" in r.json()["detail"]


@pytest.mark.parametrize("host", ["localhost", "LOCALHOST:8465", "127.0.0.1:1", "[::1]:8465", "[::1]"])
def test_the_loopback_names_are_served(offline: Served, host: str) -> None:
    served = offline
    with served.client(headers={"Host": host}) as c:
        assert c.get("/api/v1/station").status_code == 200


def test_allowed_hosts_add_names() -> None:
    from api import AllowedHosts

    hosts = AllowedHosts.of(["station-1.lab.example"], bound="192.0.2.7")
    assert hosts.allows("station-1.lab.example:8465")
    assert hosts.allows("Station-1.Lab.Example.")
    assert hosts.allows("192.0.2.7:8465")
    assert not hosts.allows("station-2.lab.example")
    assert not hosts.allows(None)
    assert not AllowedHosts.of(bound="0.0.0.0").allows("0.0.0.0")


def test_public_read_opens_the_reads_but_not_the_streams_nor_mutations(make_served: ServeFactory) -> None:
    served = make_served(sim=False, public_read=True)
    with served.client(token=False) as c:
        assert c.get("/api/v1/station").status_code == 200
        assert c.get("/api/v1/sessions").status_code == 200
        assert c.get("/api/v1/events").status_code == 401
        assert c.post("/api/v1/sessions", json=SHORT).status_code == 401


def test_a_wrong_token_is_refused(served: Served) -> None:
    with served.client(token=False, headers={"Authorization": "Bearer not-the-token-at-all"}) as c:
        r = c.post("/api/v1/sessions", json=SHORT)
    assert r.status_code == 401
    assert r.json()["code"] == "bad_token"


def test_authenticated_mutation_works(served: Served) -> None:
    with served.client() as c:
        r = c.post("/api/v1/sessions", json=SHORT)
        assert r.status_code == 201, r.text
        assert wait_final(c, r.json()["id"])["state"] == "succeeded"


@contextlib.contextmanager
def login(served: Served) -> Iterator[httpx.Client]:
    """A client holding the login cookie (as a browser that opened the printed URL), no Bearer header."""
    with httpx.Client(base_url=served.base, timeout=30) as c:
        r = c.get("/", params={"token": TOKEN}, follow_redirects=False)
        assert r.status_code == 303
        yield c


def test_login_url_sets_a_strict_httponly_cookie_that_authenticates(served: Served) -> None:
    with httpx.Client(base_url=served.base, timeout=30) as c:
        r = c.get("/", params={"token": TOKEN}, follow_redirects=False)
        assert r.status_code == 303
        assert r.headers["location"] == "/"
        cookie = r.headers["set-cookie"].lower()
        assert "httponly" in cookie
        assert "samesite=strict" in cookie
        assert c.get("/").status_code == 200
        assert c.get("/api/v1/station").status_code == 200  # the cookie alone reads
        created = c.post("/api/v1/sessions", json=SHORT, headers={"Origin": served.base})  # as the page does
        assert created.status_code == 201, created.text
        assert wait_final(c, created.json()["id"])["state"] == "succeeded"


def test_a_cookie_mutation_needs_the_pages_own_origin(offline: Served) -> None:
    """Row 3 without a browser: the cookie is sent to every port of the host, so the Origin decides."""
    served = offline
    port = served.base.rsplit(":", 1)[1]
    with login(served) as c:
        for headers in (
            {},  # no Origin and no Fetch Metadata: not the page
            {"Origin": "http://127.0.0.1:18999"},  # another port of this host
            {"Origin": f"https://127.0.0.1:{port}"},  # another scheme
            {"Origin": f"http://localhost:{port}"},  # another name than the request's Host
            {"Origin": "null"},
            {"Sec-Fetch-Site": "same-site"},
            {"Origin": "http://127.0.0.1:18999", "Sec-Fetch-Site": "same-origin"},
        ):
            r = c.post(f"/api/v1/sessions/{SID}/actions", json={"action": "abort"}, headers=headers)
            assert r.status_code == 403, (headers, r.text)
            assert r.json()["code"] == "cross_origin"
            assert "Bearer" in r.json()["detail"]
        for headers in ({"Origin": served.base}, {"Sec-Fetch-Site": "same-origin"}):
            r = c.post(f"/api/v1/sessions/{SID}/actions", json={"action": "abort"}, headers=headers)
            assert r.status_code == 404, (headers, r.text)  # past the checks: no such session
        assert c.get("/api/v1/sessions").json()["total"] == 0
    with served.client(headers={"Origin": "http://127.0.0.1:18999"}) as c:  # a script's Bearer token
        r = c.post(f"/api/v1/sessions/{SID}/actions", json={"action": "abort"})
        assert r.status_code == 404


def test_a_cookie_read_that_another_page_embeds_is_refused(served: Served) -> None:
    with login(served) as c:
        embedded = {"Sec-Fetch-Site": "same-site", "Sec-Fetch-Mode": "no-cors", "Sec-Fetch-Dest": "image"}
        r = c.get("/api/v1/camera/snapshot.png", headers=embedded)
        assert r.status_code == 403
        assert r.json()["code"] == "cross_origin"
        navigation = {"Sec-Fetch-Site": "cross-site", "Sec-Fetch-Mode": "navigate"}
        assert c.get("/api/v1/station", headers=navigation).status_code == 200
        assert c.get("/api/v1/station", headers={"Sec-Fetch-Site": "same-origin"}).status_code == 200


def test_login_with_a_wrong_token_sets_nothing(offline: Served) -> None:
    served = offline
    with httpx.Client(base_url=served.base, timeout=30) as c:
        r = c.get("/", params={"token": "wrong-token-wrong-token"}, follow_redirects=False)
    assert r.status_code == 401
    assert "set-cookie" not in r.headers


def test_station_redacts_secrets(served: Served) -> None:
    with served.client() as c:
        doc = c.get("/api/v1/station").json()
    assert doc["config"]["api"]["token"] == "***"
    assert TOKEN not in str(doc)
    assert set(doc["devices"]) == {"robot", "camera", "table", "distance_sensor"}
    deadline = time.monotonic() + 60
    while doc["devices"]["robot"]["state"] == "reading" and time.monotonic() < deadline:
        time.sleep(0.2)  # the service's first read of the arm (a thread of its own) is still under way
        with served.client() as c:
            doc = c.get("/api/v1/station").json()
    assert doc["devices"]["robot"]["state"] == "idle"
