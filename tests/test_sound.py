"""Sound: cues from the events, synthesised sample-exactly; an AAC track in the MP4; the sound card in play."""
from __future__ import annotations

import time

import numpy as np
import pytest

from driftframe.framework import audio


def _energy(x, a, b):
    return float(np.sum(np.asarray(x[int(a * audio.RATE):int(b * audio.RATE)], np.float64) ** 2))


def test_an_impact_sounds_from_its_time_on_and_not_before():
    track = audio.Soundtrack(0.0)
    blocks = []
    for k in range(60):                              # 1 s at 60 frames/s; the impact mid-frame 30
        if k == 30:
            track.impact(30.5 / 60, 5.0, 0.5)
        track.thrust(0.0)
        blocks.append(track.take(audio.frame_samples(60, k), (k + 1) / 60))
    x = np.concatenate(blocks)
    assert len(x) == audio.RATE == track.samples
    start = int(np.flatnonzero(np.abs(x) > 1e-6)[0])
    assert start == round(30.5 / 60 * audio.RATE)   # sample-exact: where the contact is inside its frame
    assert _energy(x, 0.51, 0.56) > 1.0
    assert np.abs(x).max() < 1.0


def test_louder_for_a_harder_hit_lower_for_a_bigger_body_and_the_same_samples_every_time():
    soft, hard = audio.impact(0.5, 1.0), audio.impact(8.0, 1.0)
    assert np.abs(hard).max() > 3 * np.abs(soft).max()
    small, big = audio.impact(5.0, 0.2), audio.impact(5.0, 4.0)
    zero_crossings = lambda x: np.count_nonzero(np.diff(np.sign(x[:4800])))    # noqa: E731
    assert zero_crossings(small) > 2 * zero_crossings(big)
    np.testing.assert_array_equal(audio.impact(3.0, 0.7), audio.impact(3.0, 0.7))
    near, far = audio.impact(5.0, 0.5, 5.0), audio.impact(5.0, 0.5, 70.0)     # the camera's distance, m
    np.testing.assert_allclose(np.abs(far).max() / np.abs(near).max(), 1 / 3, rtol=1e-3)


def test_thrust_is_continuous_across_blocks_and_ramps_without_a_click():
    track = audio.Soundtrack(0.0)
    x = []
    for k in range(30):
        track.thrust(1.0 if 5 <= k < 20 else 0.0)
        x.append(track.take(800, (k + 1) / 60))
    x = np.concatenate(x)
    assert _energy(x, 0.0, 4 * 800 / audio.RATE) == 0.0          # silent before the engine starts
    assert _energy(x, 6 * 800 / audio.RATE, 19 * 800 / audio.RATE) > 10.0
    assert np.abs(np.diff(x)).max() < 0.2                           # ramps, no step
    assert np.abs(x[21 * 800:]).max() == 0.0                        # off again


def test_a_billiard_break_of_many_contacts_is_bounded():
    track = audio.Soundtrack(0.0)
    for i in range(200):
        track.impact(0.001 * i, 12.0, 0.5)
    x = track.take(800, 1 / 60)
    assert len(track._voices) <= audio.MAX_VOICES and np.abs(x).max() < 1.0


@pytest.mark.gl
def test_a_recording_has_an_aac_track_of_its_length_made_of_its_collisions_and_the_same_bytes_twice(tmp_path):
    import av

    from driftframe.app import attach_rendering, make_world
    from driftframe.framework.recorder import record

    def rec(name, **options):
        world, _ = make_world("cradle")
        try:
            attach_rendering(world, size=(32, 24), hud=False, sky="lines")
            # 4 steps a frame: 1.25 s in 19 frames (0.2 s of GL here instead of 0.8)
            record(world, tmp_path / name, frames=19, steps_per_frame=4, fps=15, progress=False, **options)
        finally:
            world.close()
        return (tmp_path / name).read_bytes()

    a, b = rec("a.mp4"), rec("b.mp4")
    assert a == b                                                   # byte-identical, sound and all
    with av.open(str(tmp_path / "a.mp4")) as c:
        (s,) = c.streams.audio
        assert s.codec_context.name == "aac" and s.rate == audio.RATE
        assert float(s.duration * s.time_base) == pytest.approx(19 / 15, abs=0.03)
        x = np.concatenate([f.to_ndarray()[0] for f in c.decode(audio=0)])
    # the striker (3 m/s, 3 m from the row) hits at t = 1.0 s: quiet before, loud just after
    lag = len(x) - int(19 / 15 * audio.RATE)                           # the encoder's priming, at the start
    x = x[lag:]
    assert _energy(x, 0.0, 0.95) < 1e-3
    assert _energy(x, 1.0, 1.1) > 1.0
    rec("mute.mp4", audio=False)
    with av.open(str(tmp_path / "mute.mp4")) as c:
        assert not c.streams.audio


def test_a_speaker_on_a_device_plays_what_it_is_fed_and_none_is_one_line(capsys, monkeypatch):
    miniaudio = pytest.importorskip("miniaudio")
    from driftframe import speaker

    device = miniaudio.PlaybackDevice(output_format=miniaudio.SampleFormat.FLOAT32, nchannels=1,
                                      sample_rate=audio.RATE, backends=[miniaudio.Backend.NULL])
    sp = speaker.Speaker(device)
    try:
        sp.feed(np.full(audio.RATE, 0.1, np.float32))              # 1 s: only MAX_QUEUED s are held
        assert sp.dropped == audio.RATE - int(speaker.MAX_QUEUED * audio.RATE)
        time.sleep(0.4)                                             # the null device takes it in real time
        assert sp.starved > 0                                       # all played, then silence
    finally:
        sp.close()
        sp.close()

    def no_device(*args, **kwargs):
        raise miniaudio.MiniaudioError("failed to init device", -401)
    monkeypatch.setattr(miniaudio, "PlaybackDevice", no_device)
    assert speaker.open_speaker() is None
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no sound: no audio output device" in err


def test_the_huds_alerts_sound_once_as_they_appear(world):
    from driftframe.framework.warp import TimeWarp
    from driftframe.systems.sound import attach

    warp = TimeWarp(10)
    world.resources[TimeWarp] = warp
    track = attach(world)

    def frame():
        world.step()
        world.render()
        return track.take(800, world.time)

    assert np.abs(frame()).max() == 0.0                  # warp as asked: silence
    warp.limit = 1                                        # the governor holds it at x1: a warning
    x = np.concatenate([frame() for _ in range(16)])
    beep = audio.alert("warning")                          # from the first block's last sample (its frame's end)
    np.testing.assert_allclose(x[799:799 + len(beep)], np.tanh(beep), atol=1e-6)
    assert np.abs(np.concatenate([frame() for _ in range(8)])).max() == 0.0     # once, not every frame
    with pytest.raises(ValueError, match="alert kind must be one of warning, done, got 'beep'"):
        track.alert(0.0, "beep")
