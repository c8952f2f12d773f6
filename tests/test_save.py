"""Saves (framework/save.py): a world saved and loaded steps on to the same state hash as the run that
never stopped; a bad file is one clear error naming the file and the field."""
from __future__ import annotations

import io
import re
import json
import os
import zipfile

import numpy as np
import pytest

from driftframe import demos
from driftframe.app import make_world, simulation_systems
from driftframe.components.body import Transform, Velocity
from driftframe.framework import __version__, save, warp
from driftframe.framework.warp import TimeWarp
from driftframe.framework.inputfile import InputFileError
from driftframe.framework.output import OutputExistsError
from driftframe.framework.scene import Seed
from driftframe.framework.world import World


def _run(name, steps):
    w, _ = make_world(name)
    w.step(steps)
    return w


# short runs: k steps, save, n more (the demos' first contacts fall in the first second)
_SHORT = {"rotation": (20, 30), "spin": (20, 30), "asteroids": (30, 40), "billiards": (40, 40),
          "cradle": (40, 40), "swarm": (20, 20)}


@pytest.mark.parametrize("name", [n for n in demos.NAMES if n != "orbit"])
def test_demo_continues_bit_identically(name, tmp_path):
    k, n = _SHORT[name]
    never = _run(name, k + n)                       # the run that never stopped (nor saved)
    expected = never.state_hash()
    never.close()
    a = _run(name, k)
    path = a.save(tmp_path / f"{name}.npz")
    h_saved = a.state_hash()
    a.step(n)
    assert a.state_hash() == expected               # saving changes nothing
    a.close()
    b = World.load(path)
    assert b.state_hash() == h_saved and b.step_count == k
    b.step(n)
    assert b.state_hash() == expected
    b.close()


def test_orbit_continues_through_a_burn_and_under_warp(tmp_path):
    """The orbit demo: saved in its first burn (step 722: thrust, the autopilot turning) and under warp
    x10 (step 1000); each load steps on to the uninterrupted run's hash, and the warp comes back."""
    a = _run("orbit", 722)
    a.save(tmp_path / "burn.npz")
    a.step(1000 - 722)
    assert warp.of(a).requested == 10 and a.resources[TimeWarp].factor == 10
    a.save(tmp_path / "warp.npz")
    a.step(150)
    expected = a.state_hash()
    a.close()
    for slot in ("burn", "warp"):
        b = World.load(tmp_path / f"{slot}.npz")
        b.step(1150 - b.step_count)
        assert b.state_hash() == expected, slot
        assert warp.of(b).requested == 10
        b.close()


def test_saving_twice_gives_the_same_bytes_apart_from_nothing(tmp_path):
    a = _run("asteroids", 10)
    a.save(tmp_path / "one.npz")
    b = World.load(tmp_path / "one.npz")
    b.save(tmp_path / "two.npz")
    m1, m2 = (save.SaveFile(tmp_path / f"{s}.npz") for s in ("one", "two"))
    assert m1.manifest == m2.manifest
    a.close()
    b.close()


def test_existing_file_refused_without_overwrite_and_nothing_left_behind(tmp_path):
    a = _run("spin", 5)
    path = tmp_path / "slot.npz"
    a.save(path)
    before = path.read_bytes()
    a.step()
    with pytest.raises(OutputExistsError, match="slot.npz"):
        a.save(path)
    assert path.read_bytes() == before
    a.save(path, overwrite=True)
    b = World.load(path)
    assert b.step_count == 6
    b.close()
    assert sorted(os.listdir(tmp_path)) == ["slot.npz"]       # no part file
    a.close()


def test_a_failed_write_leaves_the_old_save_whole(tmp_path, monkeypatch):
    """Atomic: a disk that fills while the save is written leaves the last save as it was, and no part file."""
    import errno

    from driftframe.framework.output import OutputError
    a = _run("cradle", 3)
    path = tmp_path / "slot.npz"
    a.save(path)
    before = path.read_bytes()
    a.step(5)

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OutputError, match="slot.npz.*no space left"):
        a.save(path, overwrite=True)
    monkeypatch.undo()
    assert path.read_bytes() == before and sorted(os.listdir(tmp_path)) == ["slot.npz"]
    b = World.load(path)
    assert b.step_count == 3
    b.close()
    a.close()


def test_unsavable_resource_is_left_to_the_rebuild_and_a_component_is_an_error(tmp_path):
    a = _run("spin", 1)
    a.resources["callback"] = print                     # code: rebuilt, not saved
    a.resources["score"] = (3, np.float64(0.5), [float("inf"), -0.0])
    a.resources["rng"] = np.random.default_rng(7)
    a.resources["rng"].random(5)
    a.save(tmp_path / "s.npz")
    m = save.SaveFile(tmp_path / "s.npz").manifest
    assert "callback" in m["rebuilt_resources"] and "driftframe.framework.scene:SceneRecipe" in m["rebuilt_resources"]
    b = World.load(tmp_path / "s.npz")
    score = b.resources["score"]
    assert score == (3, 0.5, [float("inf"), 0.0]) and type(score[1]) is np.float64
    assert np.copysign(1.0, score[2][1]) == -1.0
    assert b.resources["rng"].random() == a.resources["rng"].random()       # the random state
    b.close()

    class Handle:
        __slots__ = ("fd",)
    ent = a.create_entity(Transform())
    a.add_component(ent, Handle())
    with pytest.raises(save.SaveError, match=f"Handle of entity {ent}"):
        a.save(tmp_path / "t.npz")
    assert not (tmp_path / "t.npz").exists()
    a.close()


class Score:
    """A type-keyed resource of the test's own (saved: plain values)."""

    def __init__(self, points: int) -> None:
        self.points = points


class Lens:
    """A type-keyed handle: not saved (the scene's build makes it again)."""
    saved = False

    def __init__(self) -> None:
        self.fd = print


def test_type_keyed_resources_are_saved_by_class_and_come_back_under_their_type(tmp_path):
    a = _run("spin", 1)
    a.resources[Score] = Score(7)
    a.resources[Lens] = Lens()
    a.save(tmp_path / "s.npz")
    m = save.SaveFile(tmp_path / "s.npz").manifest
    assert list(m["typed_resources"]) == ["driftframe.framework.scene:Seed", f"{__name__}:Score"]   # Seed: data
    assert f"{__name__}:Lens" in m["rebuilt_resources"]
    b = World.load(tmp_path / "s.npz")
    assert b.resource(Score).points == 7 and Lens not in b.resources and b.resource(Seed) == a.resource(Seed)
    b.close()
    # a save written before type keys (no typed_resources field) still loads
    member = tmp_path / "s.npz"
    with zipfile.ZipFile(member) as z:
        files = {n: z.read(n) for n in z.namelist()}
    old = json.loads(files["manifest.json"])
    del old["typed_resources"]
    old["resources"]["seed"] = 5                    # then the scene's seed was a named resource: now a Seed
    files["manifest.json"] = json.dumps(old).encode()
    with zipfile.ZipFile(tmp_path / "old.npz", "w") as z:
        for n, data in files.items():
            z.writestr(n, data)
    c = World.load(tmp_path / "old.npz")
    assert Score not in c.resources and c.state_hash() == a.state_hash()
    assert c.resource(Seed) == Seed(5) and "seed" not in dict(c.resources)
    c.close()
    a.close()


def test_own_world_loads_with_build_and_subscriptions_are_checked(tmp_path):
    from driftframe.components.collision import CollisionEvent

    def build(subscribe=True):
        w = World()
        for s in simulation_systems():
            w.add_system(s)
        if subscribe:
            w.subscribe(CollisionEvent, on_hit)
        return w

    def on_hit(event):
        pass

    a = build()
    a.create_entity(Transform(position=(1, 2, 3)), Velocity((1, 0, 0)))
    a.step(3)
    a.save(tmp_path / "own.npz")
    with pytest.raises(save.SaveError, match="own.npz: field 'scene' names no scene"):
        World.load(tmp_path / "own.npz")
    with pytest.raises(save.SaveError, match="own.npz: field 'subscriptions'"):
        World.load(tmp_path / "own.npz", build=lambda: build(False))
    b = World.load(tmp_path / "own.npz", build=build)
    a.step(5)
    b.step(5)
    assert a.state_hash() == b.state_hash()
    a.close()
    b.close()


def test_quick_load_into_the_running_world(tmp_path):
    a = _run("billiards", 30)
    h = a.state_hash()
    a.save(tmp_path / "q.npz")
    a.step(40)
    a.restore(tmp_path / "q.npz")
    assert a.state_hash() == h and a.step_count == 30
    a.step(40)
    b = _run("billiards", 70)
    assert a.state_hash() == b.state_hash()
    a.close()
    b.close()


# -- bad files: one line naming the file and the member or field --------------------------------------

@pytest.fixture(scope="module")
def good(tmp_path_factory):
    w = _run("cradle", 5)
    path = tmp_path_factory.mktemp("good") / "good.npz"
    w.save(path)
    w.close()
    return path.read_bytes()


def _rewrite(data: bytes, edit) -> bytes:
    """The save ``data`` with ``edit(name, bytes) -> (name, bytes) | None`` applied to each member."""
    src = zipfile.ZipFile(io.BytesIO(data))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for info in src.infolist():
            got = edit(info.filename, src.read(info.filename))
            if got is not None:
                z.writestr(got[0], got[1])
    return out.getvalue()


def _load_error(tmp_path, data: bytes) -> str:
    path = tmp_path / "bad.npz"
    path.write_bytes(data)
    with pytest.raises((save.SaveError, InputFileError)) as e:
        World.load(path)
    msg = str(e.value)
    assert str(path) in msg and "\n" not in msg
    return msg


def test_truncated_file(tmp_path, good):
    for cut in (10, len(good) // 2, len(good) - 30):
        assert "not a complete zip" in _load_error(tmp_path, good[:cut]) or "damaged" in \
            _load_error(tmp_path, good[:cut])


def test_flipped_byte_in_a_column_names_the_member(tmp_path, good):
    z = zipfile.ZipFile(io.BytesIO(good))
    info = z.getinfo("columns/driftframe.components.body:Transform/position.npy")
    data = bytearray(good)
    at = info.header_offset + 30 + len(info.filename) + info.file_size - 3     # a byte of the last float
    data[at] ^= 0x10
    msg = _load_error(tmp_path, bytes(data))
    assert "Transform/position.npy" in msg and "damaged" in msg


def test_flipped_byte_in_the_manifest(tmp_path, good):
    z = zipfile.ZipFile(io.BytesIO(good))
    info = z.getinfo(save.MANIFEST)
    data = bytearray(good)
    data[info.header_offset + 30 + len(info.filename) + 40] ^= 0x01
    assert "manifest.json" in _load_error(tmp_path, bytes(data))


def test_renamed_field(tmp_path, good):
    def rename(name, raw):
        if name == save.MANIFEST:
            m = json.loads(raw)
            layout = m["columnar"]["driftframe.components.body:Velocity"]
            layout["speed"] = layout.pop("linear")
            return name, json.dumps(m)
        return name.replace("Velocity/linear", "Velocity/speed"), raw
    msg = _load_error(tmp_path, _rewrite(good, rename))
    assert "columnar/driftframe.components.body:Velocity" in msg and "'speed'" in msg


def test_missing_member_and_wrong_shape(tmp_path, good):
    msg = _load_error(tmp_path, _rewrite(good, lambda n, r: None if n.endswith("Mass/kg.npy") else (n, r)))
    assert "Mass/kg.npy" in msg and "missing" in msg

    def reshape(name, raw):
        if name.endswith("Transform/position.npy"):
            out = io.BytesIO()
            np.save(out, np.zeros((3, 2)))
            return name, out.getvalue()
        return name, raw
    assert "Transform/position" in _load_error(tmp_path, _rewrite(good, reshape))


def test_edited_values_name_the_field(tmp_path, good):
    def nan_mass(name, raw):
        if name.endswith("Mass/kg.npy"):
            kg = np.lib.format.read_array(io.BytesIO(raw))
            kg[1] = -2.0
            out = io.BytesIO()
            np.lib.format.write_array(out, kg)
            return name, out.getvalue()
        return name, raw
    msg = _load_error(tmp_path, _rewrite(good, nan_mass))
    assert "columns/driftframe.components.body:Mass" in msg and "Mass.kg" in msg

    def step_text(name, raw):
        if name == save.MANIFEST:
            m = json.loads(raw)
            m["step_count"] = "five"
            return name, json.dumps(m)
        return name, raw
    assert "field 'step_count' is a str" in _load_error(tmp_path, _rewrite(good, step_text))


def test_a_builder_outside_driftframe_is_never_called(tmp_path, good):
    def builder(name, raw):
        if name == save.MANIFEST:
            m = json.loads(raw)
            assert m["scene"]["builder"] == "driftframe.app:make_world"
            assert "driftframe.framework.scene:SceneRecipe" in m["rebuilt_resources"]
            m["scene"]["builder"] = "os:system"
            return name, json.dumps(m)
        return name, raw
    assert "builder 'os:system' is not one of driftframe's" in _load_error(tmp_path, _rewrite(good, builder))


def test_foreign_files(tmp_path):
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr("hello.txt", "hi")
    assert "not a driftframe save" in _load_error(tmp_path, out.getvalue())
    out = io.BytesIO()
    np.savez(out, manifest=np.arange(3))
    assert "no manifest.json" in _load_error(tmp_path, out.getvalue())
    assert "not a complete zip" in _load_error(tmp_path, b"P5\n2 2\n255\n" + bytes(4))

    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr(save.MANIFEST, json.dumps({"format": "someone-else", "format_version": 1}))
    assert "field 'format'" in _load_error(tmp_path, out.getvalue())


def test_another_version(tmp_path, good):
    def version(fmt, pkg):
        def edit(name, raw):
            if name == save.MANIFEST:
                m = json.loads(raw)
                m["format_version"], m["driftframe_version"] = fmt, pkg
                return name, json.dumps(m)
            return name, raw
        return _rewrite(good, edit)
    msg = _load_error(tmp_path, version(save.FORMAT_VERSION + 1, "9.9.9"))
    assert "'format_version'" in msg and "9.9.9" in msg and __version__ in msg
    assert f"save format {save.FORMAT_VERSION + 1}" in msg and f"save format {save.FORMAT_VERSION}" in msg
    path = tmp_path / "same_format.npz"
    path.write_bytes(version(save.FORMAT_VERSION, "9.9.9"))       # another package, the same format: loads
    w = World.load(path)
    assert w.step_count == 5
    w.close()


def test_size_cap(tmp_path, good, monkeypatch):
    monkeypatch.setattr(save, "SAVE_CAP", len(good) - 1)
    msg = _load_error(tmp_path, good)
    assert "the limit is" in msg
    assert save.SAVE_CAP < 1 << 30


def test_tagged_values_round_trip():
    import http
    values = [(1, (2.5, "x")), [np.int32(3), np.float32(0.1)], {"a": None, 5: frozenset({1, 2})},
              np.arange(6, dtype=np.int16).reshape(2, 3), float("nan"), -0.0, True, http.HTTPStatus.OK]
    back = save.decode(json.loads(json.dumps(save.encode(values))))
    assert repr(back[:2]) == repr(values[:2]) and type(back[1][1]) is np.float32
    assert back[2] == values[2] and back[3].dtype == np.int16 and (back[3] == values[3]).all()
    assert np.isnan(back[4]) and np.copysign(1, back[5]) == -1 and back[6] is True
    assert back[7] is http.HTTPStatus.OK                  # an Enum member comes back as the member itself
    with pytest.raises(save.SaveError, match="here: unknown tag"):
        save.decode({"$pickle": "x"}, "here")


# -- the command line: record --from SAVE ----------------------------------------------------------------

def _cli(*args):
    import subprocess
    import sys
    return subprocess.run([sys.executable, "-m", "driftframe", *args], capture_output=True, text=True, timeout=300)


@pytest.mark.gl
def test_record_from_a_save_steps_on_as_the_uninterrupted_run(tmp_path):
    """A recording from a save at step 30 hashes, step by step, as the last 15 steps of the recording
    from the start (the recorder's world, rendering attached, is the one compared)."""
    a = _run("billiards", 30)
    a.save(tmp_path / "b.npz")
    a.close()
    logs = [tmp_path / "whole.txt", tmp_path / "from.txt"]
    for log, extra in zip(logs, (["--seconds", "0.75"], ["--seconds", "0.25", "--from", str(tmp_path / "b.npz")])):
        res = _cli("record", "billiards", *extra, "--size", "160x90", "--quiet", "--hash-log", str(log),
                   "-o", str(tmp_path / log.stem) + "/")
        assert res.returncode == 0, res.stderr
    whole, tail = (log.read_text().splitlines() for log in logs)
    assert len(whole) == 45 and tail == whole[30:] and tail[0].startswith("31 ")


def test_record_from_refuses_a_bad_save_in_one_line(tmp_path):
    a = _run("cradle", 2)
    a.save(tmp_path / "c.npz")
    a.close()
    res = _cli("record", "billiards", "--from", str(tmp_path / "c.npz"), "-o", str(tmp_path / "x.gif"))
    assert res.returncode == 2 and "the save is of scene 'cradle', not 'billiards'" in res.stderr
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    res = _cli("record", "cradle", "--from", str(tmp_path / "junk.npz"), "-o", str(tmp_path / "x.gif"))
    assert res.returncode == 2 and "junk.npz" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.gif").exists()


# -- play: F5 quick-save, F9 quick-load (a real window under Xvfb, real keys) ---------------------------

@pytest.fixture(scope="module")
def display():
    import shutil
    if not (shutil.which("Xvfb") and shutil.which("xdotool")):
        pytest.fail("window tests need Xvfb and xdotool: `./run tests` installs them")
    from driftframe.xvfb import virtual_display
    with virtual_display((1280, 720)) as name:
        yield name


@pytest.mark.window
@pytest.mark.gl
def test_play_f5_saves_and_f9_loads_the_world_back(display, tmp_path):
    import subprocess
    import sys
    import threading
    import time

    def xdo(*args):
        return subprocess.run(["xdotool", *args], env={**os.environ, "DISPLAY": display}, capture_output=True,
                              text=True, timeout=30)

    state = tmp_path / "state.json"
    proc = subprocess.Popen([sys.executable, "-m", "driftframe", "play", "asteroids", "--size", "320x180",
                             "--state-out", str(state), "--screenshots", str(tmp_path)],
                            env={**os.environ, "DISPLAY": display}, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline, wid = time.time() + 60, None
        while wid is None and time.time() < deadline:
            assert proc.poll() is None, proc.stderr.read()
            out = xdo("search", "--name", "driftframe").stdout.split()
            wid = out[0] if out else time.sleep(0.2)
        assert wid, "no window"
        xdo("windowfocus", "--sync", wid)
        # F5 until a save lands after the first step (on a loaded machine the window can take keys well
        # before its first step): the slot then holds a world that has moved
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
        reader.start()
        deadline = time.time() + 60
        while time.time() < deadline and not any(re.search(r"quick-save: .*\(step [1-9]", ln) for ln in lines):
            assert proc.poll() is None, "".join(lines)
            xdo("key", "--window", wid, "F5")            # the slot
            time.sleep(0.3)
        xdo("keydown", "--window", wid, "w")             # then fly away from it
        time.sleep(0.8)
        xdo("keyup", "--window", wid, "w")
        xdo("key", "--window", wid, "p")                 # paused: nothing steps after the load
        time.sleep(0.2)
        xdo("key", "--window", wid, "F9")
        time.sleep(0.3)
        xdo("keydown", "--window", wid, "Escape")
        time.sleep(0.05)
        xdo("keyup", "Escape")
        proc.wait(60)
    finally:
        if proc.poll() is None:
            proc.kill()
        xdo("keyup", "w", "Escape")
    reader.join(30)
    err = "".join(lines)
    assert proc.returncode == 0, err
    slot = tmp_path / "asteroids-quicksave.npz"
    saved = re.findall(r"quick-save: .*asteroids-quicksave\.npz \(step (\d+)\)", err)  # the last is in the slot
    saved = re.match(r"(\d+)", saved[-1]) if saved else None
    loaded = re.search(r"quick-load: .*asteroids-quicksave\.npz \(step (\d+)\)", err)
    assert saved and loaded and saved.group(1) == loaded.group(1), err
    s = json.loads(state.read_text())
    w = World.load(slot)
    assert s["steps"] == w.step_count == int(saved.group(1)) > 0
    from driftframe.app import player
    assert s["player"]["position"] == w.columns(Transform, [player(w)]).position[0].tolist()
    assert s["player"]["velocity"] == w.columns(Velocity, [player(w)]).linear[0].tolist()
    w.close()
