"""Access control: mutations, prompt answers and streams need the token; reads are open on loopback."""

from __future__ import annotations

import httpx

from tests.api.conftest import TOKEN, Served, ServeFactory, wait_final

SHORT = {"kind": "repeatability", "params": {"cycles": 3, "joints": [1], "warmup_cycles": 0}}


def test_health_needs_no_token(served: Served) -> None:
    with served.client(token=False) as c:
        r = c.get("/api/v1/health")
    assert r.status_code == 200
    assert r.json()["status"] == "ok"


def test_unauthenticated_mutations_are_refused_with_problem_details(served: Served) -> None:
    with served.client(token=False) as c:
        for method, path, body in (
            ("POST", "/api/v1/sessions", SHORT),
            ("POST", "/api/v1/sessions/abcdef123456/actions", {"action": "abort"}),
            ("POST", "/api/v1/prompt/x/confirm", {}),
            ("POST", "/api/v1/prompt/x/cancel", {}),
            ("POST", "/api/v1/measure", None),
            ("POST", "/api/v1/sessions/import", None),
            ("GET", "/api/v1/events", None),
            ("GET", "/api/v1/sessions/abcdef123456/events", None),
        ):
            r = c.request(method, path, json=body)
            assert r.status_code == 401, (method, path, r.text)
            assert r.headers["content-type"] == "application/problem+json"
            assert r.json()["code"] == "token_required"
            assert r.headers["www-authenticate"].startswith("Bearer")
        assert c.get("/api/v1/sessions").json()["total"] == 0  # nothing was created


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


def test_reads_are_open_on_loopback(served: Served) -> None:
    with served.client(token=False) as c:
        assert c.get("/api/v1/station").status_code == 200
        assert c.get("/api/v1/sessions").status_code == 200
        assert c.get("/api/v1/prompt").status_code == 204


def test_reads_need_the_token_when_open_reads_is_off(make_served: ServeFactory) -> None:
    served = make_served(open_reads=False)
    with served.client(token=False) as c:
        assert c.get("/api/v1/station").status_code == 401
        assert c.get("/api/v1/sessions").status_code == 401
        assert c.get("/api/v1/health").status_code == 200
    with served.client() as c:
        assert c.get("/api/v1/station").status_code == 200


def test_login_url_sets_a_strict_httponly_cookie_that_authenticates(served: Served) -> None:
    with httpx.Client(base_url=served.base, timeout=30) as c:
        r = c.get("/", params={"token": TOKEN}, follow_redirects=False)
        assert r.status_code == 303
        assert r.headers["location"] == "/"
        cookie = r.headers["set-cookie"].lower()
        assert "httponly" in cookie
        assert "samesite=strict" in cookie
        page = c.get("/")
        assert page.status_code == 200
        assert "text/html" in page.headers["content-type"]
        created = c.post("/api/v1/sessions", json=SHORT)  # the cookie alone
        assert created.status_code == 201, created.text
        assert wait_final(c, created.json()["id"])["state"] == "succeeded"


def test_login_with_a_wrong_token_sets_nothing(served: Served) -> None:
    with httpx.Client(base_url=served.base, timeout=30) as c:
        r = c.get("/", params={"token": "wrong-token-wrong-token"}, follow_redirects=False)
    assert r.status_code == 401
    assert "set-cookie" not in r.headers


def test_station_redacts_secrets(served: Served) -> None:
    with served.client(token=False) as c:
        doc = c.get("/api/v1/station").json()
    assert doc["config"]["api"]["token"] == "***"
    assert TOKEN not in str(doc)
    assert set(doc["devices"]) == {"robot", "camera", "table", "distance_sensor"}
    assert doc["devices"]["robot"]["state"] == "idle"
