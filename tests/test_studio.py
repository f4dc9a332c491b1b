"""Studio server: library listing and errors, safety (roots only, bounded requests), and that
every number it serves is the library's (FK, analysis, DTW alignment, spatial alignment)."""

from __future__ import annotations

import json
import socket
from urllib.parse import quote

import numpy as np
import pytest

from studio_support import MOVE, SHIFT, TURN_DEG, WALK, cli_error_line, make_library, raw_get, running_studio
from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    folder = tmp_path_factory.mktemp("studio")
    lib = make_library(folder)
    with running_studio([lib], out=folder / "out") as base:
        yield base, lib


def get_json(base, target):
    status, body = raw_get(base, target)
    return status, json.loads(body) if body else None


def test_library_lists_takes_and_the_malformed_file_with_its_error(studio):
    base, lib = studio
    status, listing = get_json(base, "/api/takes")
    assert status == 200
    ids = [t["id"] for t in listing["takes"]]
    assert ids == ["0/broken.bvh", "0/session2/walk_turned.usda", "0/walk.bvh"]  # the symlink out is not listed
    _, meta = get_json(base, "/api/meta?" + "&".join(f"id={quote(i)}" for i in ids))
    walk = read_motion(WALK, units="asf")
    assert meta["meta"]["0/walk.bvh"] == {"joints": 31, "frames": walk.n_frames, "fps": walk.fps,
                                          "duration_s": pytest.approx(walk.duration), "rig": "cmu_cgspeed",
                                          "height_m": pytest.approx(1.4258, abs=1e-3)}
    assert meta["meta"]["0/session2/walk_turned.usda"]["frames"] == walk.n_frames - SHIFT
    # the line `usdmotion info broken.bvh` prints in the library's folder
    line = cli_error_line(lib, "broken.bvh")
    assert line == "usdmotion: error: broken.bvh:4:3: OFFSET has 2 values, expected 3"
    assert meta["meta"]["0/broken.bvh"] == {"error": line}
    # the server keeps answering after the bad file
    assert get_json(base, "/api/skeleton?take=0/broken.bvh") == (422, {"error": meta["meta"]["0/broken.bvh"]["error"]})
    assert get_json(base, "/api/takes")[0] == 200


@pytest.mark.parametrize("target", [
    "/api/skeleton?take=0/../../outside.bvh", "/api/skeleton?take=0/escape.bvh",
    "/api/skeleton?take=/etc/passwd", "/api/skeleton?take=0//etc/passwd", "/api/skeleton?take=1/walk.bvh",
    "/api/positions?take=0/%2e%2e/outside.bvh", "/api/glb?take=0/./walk.bvh", "/api/skeleton?take=0/nothing.bvh",
    "/app/../../../pyproject.toml", "/vendor/three/../../package.json", "/app/%2e%2e/app.py", "/etc/passwd",
    "/app/node_modules/three/package.json", "/app/package-lock.json",
    "/api/compare?a=0/walk.bvh&b=0/escape.bvh",
])
def test_outside_the_roots_is_not_found(studio, target):
    status, _ = raw_get(studio[0], target)
    assert status == 404


def test_a_missing_take_gets_the_line_of_its_reader_and_nothing_outside_is_told(studio):
    """A take that is not there: the line `usdmotion info` prints for that name in the library's
    folder (each reader words it its own way); an id out of the roots: only "not found"."""
    base, lib = studio
    for name in ("missing.bvh", "session2/missing.usda"):
        status, body = get_json(base, f"/api/skeleton?take=0/{quote(name)}")
        assert (status, body["error"]) == (404, cli_error_line(lib, name))
        assert get_json(base, f"/api/meta?id=0/{quote(name)}")[1]["meta"][f"0/{name}"] == {"error": body["error"]}
    assert get_json(base, "/api/skeleton?take=0/session2/missing.usda")[1]["error"].endswith("no such file")
    for take, shown in [("0/../../outside.bvh", "0/../../outside.bvh"), ("0/escape.bvh", "escape.bvh"),
                        ("3/walk.bvh", "3/walk.bvh")]:  # a malformed id is shown whole
        status, body = get_json(base, f"/api/skeleton?take={quote(take)}")
        assert (status, body["error"]) == (404, f"usdmotion: error: {shown}: not found")


@pytest.mark.parametrize("target, param", [("/api/skeleton", "take"), ("/api/positions?take=", "take"),
                                           ("/api/compare?a=0/walk.bvh", "b")])
def test_a_request_that_names_no_take_is_told_so(studio, target, param):
    status, body = get_json(studio[0], target)
    assert (status, body["error"]) == (400, f"the request names no take (?{param}=ID)")


def test_a_tool_request_that_names_no_take_is_told_so(tmp_path):
    """The tool panels' JSON requests too (they look takes up through the same library)."""
    import urllib.error
    import urllib.request

    lib = make_library(tmp_path)
    with running_studio([lib], out=tmp_path / "out") as base:
        for path, body in [("/api/edit/preview", {"ops": []}), ("/api/video", {"take": ""})]:
            request = urllib.request.Request(base + path, data=json.dumps(body).encode(), method="POST",
                                             headers={"Content-Type": "application/json"})
            with pytest.raises(urllib.error.HTTPError) as answer:
                urllib.request.urlopen(request, timeout=30)
            assert answer.value.code == 400
            assert json.loads(answer.value.read())["error"] == "the request names no take (take=ID)"


def test_scripts_are_revalidated_not_refetched(studio):
    """The page's scripts carry an ETag and ``no-cache``: a reload asks again and gets 304 (no body)."""
    import http.client
    from urllib.parse import urlsplit

    url = urlsplit(studio[0])
    for path in ("/app/main.js", "/vendor/three/build/three.core.js"):
        conn = http.client.HTTPConnection(url.hostname, url.port, timeout=30)
        conn.request("GET", path)
        first = conn.getresponse()
        body = first.read()
        assert first.status == 200 and len(body) > 1000
        assert first.getheader("cache-control") == "no-cache" and first.getheader("etag")
        conn.request("GET", path, headers={"If-None-Match": first.getheader("etag")})
        again = conn.getresponse()
        assert (again.status, again.read()) == (304, b"")
        conn.close()


def test_the_render_hold_answers_empty_css_after_its_time_and_never_much_later(studio, monkeypatch):
    """``/api/hold`` (a linked page's render-blocking stylesheet, removed by the page once its take's
    first frame is drawn) answers empty CSS after ``ms``, at most MAX_HOLD_MS; nonsense is no wait."""
    import time

    from usdmotion.studio.app import MAX_HOLD_MS, hold_seconds

    for ms, low, high in (("300", 0.3, 2.0), ("soon", 0.0, 1.0)):
        t = time.perf_counter()
        status, body = raw_get(studio[0], f"/api/hold?ms={ms}")
        assert (status, body) == (200, b"") and low <= time.perf_counter() - t < high, (ms, time.perf_counter() - t)
    assert [hold_seconds(ms) for ms in ("250", "-5", "1e9", "nan", "inf", "")] == [
        0.25, 0.0, MAX_HOLD_MS / 1000, 0.0, MAX_HOLD_MS / 1000, 0.0]


def test_requests_are_read_only_and_bounded(studio):
    import http.client
    from urllib.parse import urlsplit

    url = urlsplit(studio[0])
    conn = http.client.HTTPConnection(url.hostname, url.port, timeout=30)
    conn.request("POST", "/api/takes", body=b"x" * 10)
    assert conn.getresponse().status == 405
    conn.close()
    many = "&".join(f"id=0/t{i}.bvh" for i in range(201))
    assert raw_get(studio[0], "/api/meta?" + many)[0] == 413


def test_only_requests_naming_this_machine_are_answered(studio):
    """DNS rebinding: a page of evil.example that resolves to 127.0.0.1 sends ``Host: evil.example``;
    the library must not answer it, and the studio keeps serving its own page."""
    from urllib.parse import urlsplit

    from usdmotion.studio.server import host_names

    base, port = studio[0], urlsplit(studio[0]).port
    for host in ("evil.example", f"evil.example:{port}", f"127.0.0.1.evil.example:{port}", f"LOCALHOST.evil:{port}",
                 ""):
        for target in ("/api/takes", "/", "/app/main.js", "/api/positions?take=0/walk.bvh"):
            status, body = raw_get(base, target, host_header=host)
            assert status == 400, (host, target)
            assert b"walk" not in body and b"does not answer" in body
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", "LocalHost", f"[::1]:{port}", "192.168.1.20:8765"):
        status, body = raw_get(base, "/api/takes", host_header=host)
        assert status == 200 and b"walk.bvh" in body, host
    assert raw_get(base, "/")[0] == 200
    assert host_names("0.0.0.0") == [socket.gethostname().lower()]
    assert host_names("studio.lab", ["Coach-PC", "[::1]"]) == ["studio.lab", "coach-pc", "::1"]


def test_the_rig_column_names_cmu_asf_amc_takes(tmp_path, shared_file):
    """86_01.amc's bones (root, lfemur, lwrist...) fit the 'cmu_asf' profile (CMU's own ASF/AMC
    skeletons); the library names their family by it."""
    import shutil

    from usdmotion.skeleton_names import rig_profiles
    from usdmotion.studio.library import Library

    lib = tmp_path / "lib"
    lib.mkdir()
    for name in ("86.asf", "86_01.amc"):
        shutil.copy(shared_file(f"cmu86/{name}"), lib / name)
    shutil.copy(WALK, lib / "walk.bvh")
    library = Library([lib], {"units": "asf"})
    meta = {e.name: library.metadata(e) for e in library.scan()}
    names = read_motion(lib / "86_01.amc").joint_names
    assert set(rig_profiles()["cmu_asf"]["signature"]) <= set(names)
    assert meta["86_01.amc"]["rig"] == "cmu_asf" and meta["86_01.amc"]["joints"] == 31
    assert meta["walk.bvh"]["rig"] == "cmu_cgspeed"  # an automatic-map profile still wins where one fits


def test_positions_are_the_library_fk_in_metres(studio):
    base, lib = studio
    status, body = raw_get(base, "/api/positions?take=0/walk.bvh")
    walk = read_motion(lib / "walk.bvh", units="asf")
    served = np.frombuffer(body, dtype=np.float32).reshape(walk.n_frames, walk.n_joints, 3)
    np.testing.assert_allclose(served, joint_positions(walk) * walk.meters_per_unit, atol=1e-5)


def test_a_linked_page_starts_reading_its_take(tmp_path, monkeypatch):
    """``GET /?take=ID`` starts computing the take's positions (its page asks for them next); they are
    computed once and are the library's FK; links to missing or broken takes still get the page."""
    import time

    from usdmotion.studio import takes

    lib = make_library(tmp_path)
    computed, view_positions = [], takes.view_positions
    monkeypatch.setattr(takes, "view_positions",
                        lambda motion: computed.append(motion.n_frames) or view_positions(motion))
    with running_studio([lib], out=tmp_path / "out") as base:
        assert raw_get(base, "/?take=0/walk.bvh")[0] == 200
        deadline = time.monotonic() + 60
        while not computed and time.monotonic() < deadline:
            time.sleep(0.02)
        walk = read_motion(lib / "walk.bvh", units="asf")
        assert computed == [walk.n_frames]  # before any request for them
        status, body = raw_get(base, "/api/positions?take=0/walk.bvh")
        assert status == 200 and computed == [walk.n_frames]  # not again
        served = np.frombuffer(body, dtype=np.float32).reshape(walk.n_frames, walk.n_joints, 3)
        np.testing.assert_allclose(served, joint_positions(walk) * walk.meters_per_unit, atol=1e-5)
        for bad in ("0/missing.bvh", "0/broken.bvh", "0/../../outside.bvh", "0/escape.bvh"):
            assert raw_get(base, f"/?take={bad}")[0] == 200
        assert get_json(base, "/api/skeleton?take=0/broken.bvh") == (
            422, {"error": "usdmotion: error: broken.bvh:4:3: OFFSET has 2 values, expected 3"})
        assert computed == [walk.n_frames]  # nothing read out of the root


def test_series_are_the_analysis_module(studio):
    from usdmotion.anthropometry import body_model
    from usdmotion.ops.analyse import analyse

    base, lib = studio
    _, s = get_json(base, "/api/series?take=0/walk.bvh&joints=LeftLeg,RightUpLeg&q=bend,speed,com_height")
    walk = read_motion(lib / "walk.bvh", units="asf")
    kin = analyse(walk, body=body_model(walk))
    j = walk.joint_index("LeftLeg")
    by_label = {x["label"]: np.array(x["values"], dtype=float) for x in s["series"]}
    assert [x["unit"] for x in s["series"]] == ["deg", "deg", "m/s", "m/s", "m"]
    np.testing.assert_allclose(by_label["LeftLeg joint angle"], kin.bend[:, j], atol=1e-4)
    np.testing.assert_allclose(by_label["LeftLeg joint speed"], np.linalg.norm(kin.velocities[:, j], axis=1), atol=1e-4)
    np.testing.assert_allclose(by_label["centre-of-mass height"], kin.com[:, 1], atol=1e-4)
    assert 0.7 < np.nanmean(by_label["centre-of-mass height"]) < 1.0  # metres, a walking adult
    assert get_json(base, "/api/series?take=0/walk.bvh&joints=Nope")[0] == 400


def test_compare_finds_the_shift_in_time_and_undoes_the_turn(studio):
    base, lib = studio
    _, answer = get_json(base, "/api/compare?a=0/session2/walk_turned.usda&b=0/walk.bvh&mode=dtw&frame=100")
    frame_map = np.array(answer["map"])
    inner = frame_map[20:-20]  # DTW's ends are open
    assert np.median(np.abs(inner - (np.arange(len(frame_map)) + SHIFT)[20:-20])) <= 1.0
    # spatial: the walk moved by the alignment matrix lands on the turned take, all joints, at the aligned frame
    a = read_motion(lib / "session2" / "walk_turned.usda")
    b = read_motion(lib / "walk.bvh", units="asf")
    m = np.array(answer["align"])
    fb = int(round(frame_map[100]))
    pb = joint_positions(b)[fb] * b.meters_per_unit
    pa = joint_positions(a)[100] * a.meters_per_unit
    moved = pb @ m[:3, :3].T + m[:3, 3]
    # heading is smoothed over 0.5 s, so allow a few degrees and centimetres
    assert np.abs(moved - pa)[:, [0, 2]].max() < 0.06
    turn = np.degrees(np.arctan2(m[0, 2], m[0, 0]))
    assert abs(abs(turn) - TURN_DEG) < 5.0
    _, manual = get_json(base, "/api/compare?a=0/walk.bvh&b=0/session2/walk_turned.usda&mode=offset&offset=0.5")
    np.testing.assert_allclose(manual["map"][60:70], np.arange(60, 70) - 0.5 * 120, atol=1e-6)
    assert MOVE  # the move is part of the fixture; the alignment absorbs it


def test_glb_is_the_writers_body_and_is_cached_only_in_the_output_folder(studio):
    from usdmotion.io.gltf import glb_bytes

    base, lib = studio
    before = sorted(p for p in lib.parent.rglob("*") if p.is_file())
    status, first = raw_get(base, "/api/glb?take=0/walk.bvh")
    assert status == 200 and first[:4] == b"glTF"
    assert first == glb_bytes(read_motion(lib / "walk.bvh", units="asf"), mesh=True)
    written = sorted(set(p for p in lib.parent.rglob("*") if p.is_file()) - set(before))
    assert [p.parent.relative_to(lib.parent).as_posix() for p in written] == ["out/cache/glb"]
    assert written[0].read_bytes() == first


def test_a_huge_file_is_listed_with_an_error_and_not_read(studio, monkeypatch):
    import usdmotion.studio.library as library

    base, lib = studio
    (lib / "huge").mkdir()
    (lib / "huge" / "long.bvh").write_bytes(WALK.read_bytes())
    monkeypatch.setattr(library, "MAX_FILE_BYTES", 100_000)
    try:
        _, meta = get_json(base, "/api/meta?id=0/huge/long.bvh")
        size = WALK.stat().st_size
        assert meta["meta"]["0/huge/long.bvh"] == {
            "error": f"usdmotion: error: huge/long.bvh: file is {size:,} bytes; the studio reads files up to "
                     "100,000 bytes"}
        assert get_json(base, "/api/positions?take=0/huge/long.bvh")[0] == 422
        assert get_json(base, "/api/takes")[0] == 200
    finally:
        (lib / "huge" / "long.bvh").unlink()
        (lib / "huge").rmdir()


def test_listing_thousands_of_files_reads_none_of_them(tmp_path):
    from usdmotion.studio.library import Library

    tiny = WALK.read_bytes()[:2000]  # never parsed: listing must not read files
    for i in range(2000):
        folder = tmp_path / f"athlete{i % 20:02d}"
        folder.mkdir(exist_ok=True)
        (folder / f"take{i:04d}.bvh").write_bytes(tiny)
    read = []
    library = Library([tmp_path], read=lambda entry: read.append(entry))
    entries = library.scan()
    assert len(entries) == 2000 and entries[0].id == "0/athlete00/take0000.bvh"
    assert read == []  # metadata is read only when asked for, one take at a time
    assert library.resolve("0/athlete07/take0007.bvh").path == tmp_path / "athlete07" / "take0007.bvh"


def test_a_z_up_take_is_turned_to_the_viewers_y_up_like_its_glb(tmp_path):
    import dataclasses

    from pygltflib import GLTF2

    from usdmotion.io.gltf import glb_bytes
    from usdmotion.studio.takes import view_positions

    walk = read_motion(WALK, units="asf")
    z_up = dataclasses.replace(walk, up_axis="Z")
    p = view_positions(z_up)
    fk = joint_positions(z_up) * z_up.meters_per_unit
    np.testing.assert_allclose(p, np.stack([fk[..., 0], fk[..., 2], -fk[..., 1]], axis=-1), atol=1e-5)
    # the GLB writer turns the same way: its root node carries the rotation taking Z-up to Y-up
    gltf = GLTF2.load_from_bytes(glb_bytes(z_up))
    x, y, z, w = gltf.nodes[0].rotation
    angle = 2 * np.degrees(np.arctan2(np.linalg.norm([x, y, z]), w))
    assert abs(angle - 90) < 1e-4 and abs(abs(x) - np.sqrt(0.5)) < 1e-6 and np.sign(x) == -np.sign(w)
