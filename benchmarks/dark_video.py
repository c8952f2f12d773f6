"""Streaks on black: which x264 options (and a dither of the source) keep dark areas clean, at what CPU?

Issue 25: "faint x264 streaks show on black backgrounds". The scene is the
``asteroids`` demo with its default sky (the starfield) at 640x360, one step
a frame at 60 fps (as ``driftframe record``), 240 frames, converted to NV12 once, exactly as the recorder
hands x264 its frames (:func:`framework.yuv.rgba_to_nv12`). Each variant
encodes the same frames through the recorder's own encoder
(:class:`framework.record_sinks._H264Sink`: x264 through PyAV, one thread);
the variants run interleaved, round after round, and each one's encoder CPU
(``time.process_time``) is the median over rounds. The decoded luma is
compared with the luma handed to x264, over the dark pixels (source luma
under 40 of 16..235):

- *RMS* error and the share of pixels off by 4 levels or more;
- *lines*: streaks, thin lines of error: :func:`_line_errors`;
- *block-edge steps*: neighbouring dark pixels across a 4x4 transform
  block's edge whose decoded values differ by 2 levels or more where the
  source's differ by at most 1, for 4 pixels in a row along the edge with the
  same sign (a line a viewer sees), per frame; beside it the same count at the
  half-block offset (2 mod 4), which no block edge crosses: the count a
  smooth error leaves anyway. Streaks from the codec's blocks are the excess.

A dither variant rounds the source's luma with a fixed 4x4 Bayer pattern
instead of to nearest (the same pattern every frame, so still the same bytes
every run). The cost of a variant is its encoder CPU beyond the first row's
(the settings before issue 25), as a share of what a recording costs a frame in
all (step, render, read-back, conversion and encoding, measured on the same
frames here); issue 25 keeps an option only below 5 %. The crop where the
first row has the most streaks, magnified 8x with luma 16-56 stretched to
black-white, goes to ``docs/img/dark_video.png`` (source, then variants) to look at.

    python -m benchmarks.dark_video [--quick]
"""
from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import IMG, parser, table, write_section
from benchmarks.record_throughput import _swapped
from driftframe.framework import record_sinks
from driftframe.framework.gl import RenderTarget, create_context
from driftframe.framework.yuv import rgba_to_nv12

NAME = "dark_video"
SIZE = (640, 360)
STEPS_PER_FRAME = 1            # as `driftframe record` at its default --fps 60
FPS = 60
DARK = 40                       # source luma below this (of 16..235) counts as dark
#: What a variant may add to a recording's CPU a frame (issue 25).
COST_BAR = 0.05
_BEFORE = "cabac=1:deblock=0,0"          # the default before issue 25 (deblocking on, offsets 0)
_KEPT = _BEFORE + ":deadzone-inter=6:deadzone-intra=6:keyint=60"      # issue 25's choice

#: (label, x264 options beyond the preset and crf, source: "plain" or "dither"). The first is the baseline.
VARIANTS = (
    ("before: cabac=1:deblock=0,0", {"x264-params": _BEFORE}, "plain"),
    ("no deblocking", {"x264-params": "cabac=1:no-deblock=1"}, "plain"),
    ("deblock=1,1 (stronger)", {"x264-params": "cabac=1:deblock=1,1"}, "plain"),
    ("tune film (deblock -1,-1)", {"tune": "film", "x264-params": "cabac=1:deblock=-1,-1"}, "plain"),
    ("tune grain (deblock -2,-2)", {"tune": "grain", "x264-params": "cabac=1:deblock=-2,-2"}, "plain"),
    ("tune stillimage (deblock -3,-3)", {"tune": "stillimage", "x264-params": "cabac=1:deblock=-3,-3"}, "plain"),
    ("no-fast-pskip", {"x264-params": _BEFORE + ":no-fast-pskip=1"}, "plain"),
    ("no-dct-decimate", {"x264-params": _BEFORE + ":no-dct-decimate=1"}, "plain"),
    ("aq-mode=3", {"x264-params": _BEFORE + ":aq-mode=3"}, "plain"),
    ("Bayer 4x4 dither of luma", {"x264-params": _BEFORE}, "dither"),
    ("deadzone 6/6 (grain's)", {"x264-params": _BEFORE + ":deadzone-inter=6:deadzone-intra=6"}, "plain"),
    ("keyint=60 (1 s)", {"x264-params": _BEFORE + ":keyint=60"}, "plain"),
    ("deadzone 6/6 + keyint=60 (kept)", {"x264-params": _KEPT}, "plain"),
    ("crf 23", {"x264-params": _BEFORE, "crf": "23"}, "plain"),
    ("crf 24 + deadzone 6/6 + keyint=60", {"x264-params": _KEPT, "crf": "24"}, "plain"),
)

# 4x4 Bayer thresholds in (0, 1): (k + 0.5) / 16
_BAYER = (np.array([[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]]) + 0.5) / 16


def _frames(demo: str, count: int) -> tuple[list[np.ndarray], list[np.ndarray], float]:
    """NV12 frames as the recorder makes them, the same with the luma Bayer-dithered, and the median CPU
    seconds a frame of step + render + read-back + conversion."""
    from driftframe.app import attach_rendering, make_world

    w, h = SIZE
    ctx = create_context()
    world, _ = make_world(demo, seed=1)
    attach_rendering(world, ctx, size=SIZE, own_context=False)
    target = world.resources[RenderTarget]
    plain, dithered = [], []
    kr, kb = 0.2126, 0.0722
    threshold = np.tile(_BAYER, (h // 4, w // 4))
    cpu = []
    try:
        world.step()
        world.render()
        target.read_raw()                       # warm-up (shaders, buffers, kernels loaded), not a frame
        for _ in range(count):
            c0 = time.process_time()
            for _ in range(STEPS_PER_FRAME):
                world.step()
            world.render()
            raw = target.read_raw()
            nv12 = rgba_to_nv12(raw, w, h)
            cpu.append(time.process_time() - c0)
            plain.append(nv12)
            rgb = np.frombuffer(raw, np.uint8).reshape(h, w, 4)[::-1, :, :3].astype(np.float64)
            luma = 16 + 219 / 255 * (kr * rgb[..., 0] + (1 - kr - kb) * rgb[..., 1] + kb * rgb[..., 2])
            d = nv12.copy()
            d[:w * h] = np.floor(luma + threshold).astype(np.uint8).ravel()
            dithered.append(d)
    finally:
        world.close()
    return plain, dithered, statistics.median(cpu)


def _encode(frames: list[np.ndarray], path: Path, options: dict) -> float:
    """Encoder CPU seconds a frame of ``frames`` through the recorder's sink with ``options``."""
    options = dict(options)
    crf = int(options.pop("crf", record_sinks.X264_CRF["ultrafast"]))
    with _swapped(X264_TUNING={"ultrafast": options}):
        c0 = time.process_time()
        sink = record_sinks._H264Sink(path, SIZE, FPS, crf=crf, preset="ultrafast", pixel_format="nv12")
        for f in frames:
            sink.write(f)
        sink.finish()
        return (time.process_time() - c0) / len(frames)


def _decoded_luma(path: Path) -> np.ndarray:
    import av

    w, h = SIZE
    with av.open(str(path)) as video:
        return np.stack([f.to_ndarray(format="nv12")[:h] for f in video.decode(video=0)])


def _runs4(step: np.ndarray) -> int:
    """Places where 4 pixels in a row along axis 1 all carry a step of the same sign (+1 / -1 / 0)."""
    s = step
    same = (s[:, :-3] != 0) & (s[:, :-3] == s[:, 1:-2]) & (s[:, :-3] == s[:, 2:-1]) & (s[:, :-3] == s[:, 3:])
    return int(same.sum())


def streaks(src: np.ndarray, dec: np.ndarray, offset: int) -> int:
    """Visible steps 4 pixels long along lines ``x = 4k + offset`` and ``y = 4k + offset`` in dark areas.

    A step between neighbours p (before the line) and q (after): both dark in
    the source, ``|dec q - dec p| >= 2`` and ``|src q - src p| <= 1``; its sign is
    kept, and 4 consecutive steps of one sign along the line make one count.
    """
    s, d = src.astype(np.int16), dec.astype(np.int16)
    total = 0
    for a, b in ((s, d), (s.transpose(0, 2, 1), d.transpose(0, 2, 1))):   # across vertical, then horizontal lines
        cols = np.arange(4 + offset, a.shape[2], 4)
        p, q = cols - 1, cols
        dark = (a[:, :, p] < DARK) & (a[:, :, q] < DARK)
        flat = np.abs(a[:, :, q] - a[:, :, p]) <= 1
        jump = b[:, :, q] - b[:, :, p]
        step = np.where(dark & flat & (np.abs(jump) >= 2), np.sign(jump), 0)      # (frames, rows, lines)
        total += _runs4(step.transpose(0, 2, 1).reshape(-1, step.shape[1]))
    return total


def _line_errors(src: np.ndarray, dec: np.ndarray) -> np.ndarray:
    """Where the error forms thin lines: (frames, windows, columns) of high-passed 16-pixel means.

    The error ``dec - src`` is averaged over 16 pixels down each column (a
    window: all 16 source pixels dark), and the mean of the two neighbouring
    columns' windows is taken off. What is left is error that a column has
    and its neighbours lack: a vertical streak. Noise that changes from pixel to
    pixel averages out (RMS 1 level gives about 0.3 here); a level block-wide
    offset cancels. NaN where a window or a neighbour is not all dark.
    """
    f, h, w = src.shape
    h16 = h // 16 * 16
    e = (dec[:, :h16].astype(np.float32) - src[:, :h16]).reshape(f, h16 // 16, 16, w).mean(axis=2)
    dark = (src[:, :h16] < DARK).reshape(f, h16 // 16, 16, w).all(axis=2)
    hp = e[:, :, 1:-1] - 0.5 * (e[:, :, :-2] + e[:, :, 2:])
    ok = dark[:, :, 1:-1] & dark[:, :, :-2] & dark[:, :, 2:]
    return np.where(ok, hp, np.nan)


#: A line's mean error (levels, over 16 pixels) that counts as a streak: one level, which the 8x crops show.
LINE = 1.0


def quality(src_luma: np.ndarray, dec: np.ndarray) -> dict:
    dark = src_luma < DARK
    err = dec[dark].astype(np.float64) - src_luma[dark]
    n = len(src_luma)
    lines = np.zeros(n)                                 # a frame's
    for s, d in ((src_luma, dec), (src_luma.transpose(0, 2, 1), dec.transpose(0, 2, 1))):  # columns, then rows
        lines += (np.nan_to_num(np.abs(_line_errors(s, d)), nan=0.0) >= LINE).sum(axis=(1, 2))
    # a keyframe resets the error a run of P-frames built up: seen as a pulse, the dark RMS jumping at once
    e2 = np.where(dark, (dec.astype(np.float64) - src_luma) ** 2, 0.0).sum(axis=(1, 2))
    per_frame = np.sqrt(e2 / np.maximum(dark.sum(axis=(1, 2)), 1))
    return {"rms": float(np.sqrt((err ** 2).mean())), "off4": float((np.abs(err) >= 4).mean()),
            "pulse": float(np.abs(np.diff(per_frame)).max()), "lines": float(lines.mean()),
            "lines_first": float(lines[:30].mean()), "lines_last": float(lines[-30:].mean()),
            "edge": streaks(src_luma, dec, 0) / n, "mid": streaks(src_luma, dec, 2) / n}


def _crop_at(src_luma: np.ndarray, dec: np.ndarray, cw: int = 80, ch: int = 48) -> tuple[int, int, int]:
    """(frame, y, x) of the crop where ``dec`` has the most vertical streaks (:func:`_line_errors`)."""
    hp = np.nan_to_num(np.abs(_line_errors(src_luma, dec)), nan=0.0) >= LINE    # (frames, h / 16, w - 2)
    per = hp[:, :hp.shape[1] // 3 * 3, :hp.shape[2] // cw * cw]
    per = per.reshape(len(hp), per.shape[1] // 3, 3, per.shape[2] // cw, cw).sum(axis=(2, 4))
    fi, yi, xi = np.unravel_index(int(per.argmax()), per.shape)
    return int(fi), int(yi) * ch, int(xi) * cw + 1


def _magnified(luma: np.ndarray, lo: int = 16, hi: int = 56, k: int = 8) -> np.ndarray:
    v = np.clip((luma.astype(np.float64) - lo) * 255 / (hi - lo), 0, 255).astype(np.uint8)
    return np.repeat(np.repeat(v, k, axis=0), k, axis=1)


def _picture(panels: list[tuple[str, np.ndarray]], path: Path) -> None:
    from PIL import Image, ImageDraw

    cols = 2
    tiles = [_magnified(p) for _, p in panels]
    th, tw = tiles[0].shape
    rows = -(-len(tiles) // cols)
    sheet = Image.new("L", (cols * (tw + 8), rows * (th + 22)), 96)
    draw = ImageDraw.Draw(sheet)
    for k, ((label, _), tile) in enumerate(zip(panels, tiles)):
        x, y = (k % cols) * (tw + 8), (k // cols) * (th + 22)
        sheet.paste(Image.fromarray(tile), (x, y + 18))
        draw.text((x + 2, y + 3), label, fill=255)
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)


def _measure(plain, dithered, src_luma, rounds: int):
    """Per variant: encoder CPU seconds a frame (one list entry a round), bytes, quality, decoded luma."""
    cpu: dict[str, list[float]] = {label: [] for label, _, _ in VARIANTS}
    sizes, scores, decoded = {}, {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "v.mp4"
        _encode(plain[:30], path, VARIANTS[0][1])               # warm-up: PyAV, x264's tables
        for r in range(rounds):
            order = VARIANTS[r % len(VARIANTS):] + VARIANTS[:r % len(VARIANTS)]     # rotate: no fixed position
            for label, options, source in order:
                cpu[label].append(_encode(dithered if source == "dither" else plain, path, options))
                if r:
                    continue
                sizes[label] = path.stat().st_size
                decoded[label] = dec = _decoded_luma(path)
                scores[label] = q = quality(src_luma, dec)
                print(f"{label:>32}: {cpu[label][-1] * 1e3:5.2f} ms, {sizes[label] / 1024:5.0f} KiB, "
                      f"RMS {q['rms']:.2f}, off by 4+ {q['off4']:.2%}, lines {q['lines']:.1f}, edge steps "
                      f"{q['edge']:.1f} (mid-block {q['mid']:.1f}) a frame", flush=True)
    return cpu, sizes, scores, decoded


def throughput(frames: int, rounds: int) -> dict[str, tuple[float, float, float]]:
    """Whole recordings as ``benchmarks.record_throughput`` makes them (asteroids, 1280x720, the recorder's
    defaults) with the x264 settings before and kept, beside the bare loop, interleaved: per mode the median
    frames/s, the median, least and most share of the bare loop's frames/s in the same round, and the
    CPU milliseconds a frame."""
    from benchmarks import record_throughput as rt

    ctx = create_context()
    modes = {"bare": None, "before": {"ultrafast": {"x264-params": _BEFORE}},
             "kept": {"ultrafast": {"x264-params": _KEPT}}}
    fps: dict[str, list[float]] = {m: [] for m in modes}
    cpu: dict[str, list[float]] = {m: [] for m in modes}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            names = list(modes)[r % 3:] + list(modes)[:r % 3]
            for m in names:
                c0 = time.process_time()
                if modes[m] is None:
                    fps[m].append(rt.bare(ctx, frames))
                else:
                    fps[m].append(rt.recorded(ctx, frames, Path(tmp) / f"t{r}{m}.mp4", _tuning=modes[m])[0])
                cpu[m].append((time.process_time() - c0) / frames)
    shares = {m: [f / b for f, b in zip(fps[m], fps["bare"])] for m in modes}
    return {m: (statistics.median(fps[m]), statistics.median(shares[m]), min(shares[m]), max(shares[m]),
                statistics.median(cpu[m]) * 1e3) for m in modes}


def _verdict(scores: dict, sizes: dict, ms: dict, record_ms: float) -> str:
    """What the table says, in words, with its figures."""
    b, k, c = "before: cabac=1:deblock=0,0", "deadzone 6/6 + keyint=60 (kept)", "crf 24 + deadzone 6/6 + keyint=60"
    d = "Bayer 4x4 dither of luma"
    tunes = [(t, f"tune {t} ({o})") for t, o in (("film", "deblock -1,-1"), ("grain", "deblock -2,-2"),
                                                  ("stillimage", "deblock -3,-3"))]

    def fig(v):
        q = scores[v]
        return (f"lines {q['lines']:.0f}, dark RMS {q['rms']:.2f}, off by 4+ {q['off4']:.1%}, "
                f"{sizes[v] / sizes[b]:.2f}x the bytes, {(ms[v] - ms[b]) / record_ms:+.1%} CPU")

    return ("**Kept** (`record_sinks.X264_TUNING`): x264's quantiser deadzone down to 6 (from 21 inter, 11 "
            "intra; `--tune grain`'s value: ultrafast has no trellis, so the deadzone alone decides which small "
            "coefficients are dropped, and on black those are the corrections) and a keyframe every 60 frames "
            "(from 250): the error that P-frames pile up in dark areas, speckle in columns and rows (the "
            f"before row's *lines*: {scores[b]['lines_first']:.0f} a frame over the first 30 frames, "
            f"{scores[b]['lines_last']:.0f} over the last 30), is cleared each second. Before: {fig(b)}; "
            f"kept: {fig(k)}. Deblocking was on already (`deblock=0,0` turns it on at offsets 0; x264's SEI "
            "reads `deblock=1:0:0`): off, the block-edge steps rise "
            f"{scores['no deblocking']['edge'] / scores[b]['edge']:.0f}-fold. Of the `--tune` presets film and "
            "stillimage change only the deblocking offsets under ultrafast (their psy settings need subme 6 or "
            "trellis, which ultrafast lacks: x264's SEI); grain also sets the deadzone to 6, turns off DCT "
            "decimation and sets qcomp 0.8 and ip-ratio 1.1. Their lines: "
            + ", ".join(f"{t} {scores[v]['lines']:.0f}" for t, v in tunes) + f" (before: {scores[b]['lines']:.0f}). "
            f"The Bayer dither of the luma: {sizes[d] / sizes[b]:.3f}x the bytes, lines {scores[d]['lines']:.0f} "
            "(x264 drops a +/-1 "
            "pattern at crf 26), and the galactic band's 8-bit steps are in the RGBA already, where a dither of "
            "the conversion cannot reach. What remains with the kept settings: faint speckle late in each "
            f"1 s run of P-frames (8x, levels stretched), and a keyframe's reset (pulse {scores[k]['pulse']:.2f} "
            f"levels of dark RMS; keyint alone {scores['keyint=60 (1 s)']['pulse']:.2f}). crf 24 on top would "
            f"take the lines down again ({fig(c)}) at a crf that issue 11 chose for the bytes; left for a "
            "decision.")


#: The variants shown in the picture beside the source.
SHOWN = ("before: cabac=1:deblock=0,0", "tune grain (deblock -2,-2)", "Bayer 4x4 dither of luma", "crf 23",
         "deadzone 6/6 (grain's)", "keyint=60 (1 s)", "deadzone 6/6 + keyint=60 (kept)")


def main(argv=None) -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--demo", default="asteroids")
    p.add_argument("--crops", type=Path, default=None, help="also write each variant's crop here (a folder)")
    args = p.parse_args(argv)
    if record_sinks.X264_TUNING["ultrafast"]["x264-params"] != _KEPT:
        print("note: the recorder's x264 settings are no longer this benchmark's 'kept' row")
    started = time.perf_counter()
    count, rounds = (40, 1) if args.quick else (240, 5)
    w, h = SIZE
    plain, dithered, frame_cpu = _frames(args.demo, count)
    src_luma = np.stack([f[:w * h].reshape(h, w) for f in plain])
    load0 = os.getloadavg()[0]
    cpu, sizes, scores, decoded = _measure(plain, dithered, src_luma, rounds)
    load1 = os.getloadavg()[0]
    ms = {label: statistics.median(v) * 1e3 for label, v in cpu.items()}
    base = VARIANTS[0][0]
    record_ms = frame_cpu * 1e3 + ms[base]
    rows = []
    for label, _, _ in VARIANTS:
        q = scores[label]
        cost = (ms[label] - ms[base]) / record_ms
        rows.append([label, f"{ms[label]:.2f}", f"{cost:+.1%}" + (" (over the bar)" if cost > COST_BAR else ""),
                     f"{sizes[label] / count / 1024:.2f} KiB", f"{q['rms']:.2f}", f"{q['off4']:.1%}",
                     f"{q['pulse']:.2f}", f"{q['lines']:.1f}", f"{q['edge']:.1f} ({q['mid']:.1f})"])
    tp = throughput(20 if args.quick else 240, 1 if args.quick else 5)
    fi, y, x = _crop_at(src_luma, decoded[base])
    crop = np.s_[fi, y:y + 48, x:x + 80]
    _picture([("source (the luma x264 is given)", src_luma[crop])] + [(v, decoded[v][crop]) for v in SHOWN],
             IMG / f"{NAME}.png")
    if args.crops is not None:
        for k, (label, _, _) in enumerate(VARIANTS):
            _picture([("source", src_luma[crop]), (label, decoded[label][crop])], args.crops / f"crop_{k:02d}.png")
    body = (f"`{args.demo}`, default sky (the starfield), {w}x{h}, {count} frames at {FPS} fps (one step each, "
            f"as `driftframe record`), x264 ultrafast crf {record_sinks.X264_CRF['ultrafast']}, one thread, "
            f"through the recorder's own encoder; {rounds} interleaved rounds, x264 CPU the median "
            f"(`time.process_time`; load average {load0:.1f} at the start, {load1:.1f} at the end). Dark: source "
            f"luma under {DARK} (of 16-235). *Cost*: x264 CPU beyond the first row's, as a share of a "
            f"recording's CPU a frame here ({record_ms:.1f} ms: step, render, read-back and NV12 "
            f"{frame_cpu * 1e3:.1f} ms + x264 {ms[base]:.2f} ms). *Pulse*: the largest change of the dark RMS "
            "from one frame to the next (a keyframe's reset shows). *Lines*: 16-pixel runs of a column (or row) "
            f"whose mean error differs by {LINE:g} level or more from its two neighbours', all dark, a frame "
            "(streaks). *Block-edge steps*: 4-pixel runs of a decoded step of 2+ levels where the source is flat, "
            "on 4x4 block edges, a frame; in brackets the same count half a block away, where no edge is.\n\n"
            + table(["variant", "x264 CPU a frame, ms", "cost", "size a frame", "dark RMS, levels", "off by 4+",
                     "pulse", "lines", "block-edge steps"], rows)
            + "\n\n" + _verdict(scores, sizes, ms, record_ms)
            + "\n\n**Throughput** (the bar: under 5 % lost). Whole recordings as `benchmarks.record_throughput` "
            f"makes them (asteroids, 1280x720, {20 if args.quick else 240} frames, the recorder's defaults but for "
            "the x264 settings), interleaved with the bare step + render + read-back loop, "
            f"{1 if args.quick else 5} rounds, medians; CPU a frame includes building the world.\n\n"
            + table(["x264 settings", "frames/s", "share of bare (rounds' range)", "CPU a frame, ms"],
                    [[k, f"{v[0]:.1f}", f"{v[1]:.2f} ({v[2]:.2f}-{v[3]:.2f})", f"{v[4]:.1f}"] for k, v in
                     (("none (bare loop)", tp["bare"]), (_BEFORE + " (before)", tp["before"]),
                      (_KEPT + " (kept)", tp["kept"]))])
            + f"\n\nThe kept settings' CPU a frame: {tp['kept'][4] / tp['before'][4] - 1:+.1%} of before's (what "
            "bounds the rate on 2 shared cores; the frames/s move with other work on the machine, both ways)."
            + f"\n\nThe picture: frame {fi}, x {x}-{x + 79}, y {y}-{y + 47} (where the first row has the most "
            "lines), magnified 8x, luma 16-56 stretched to black-white: the source, then the decoded video.")
    write_section(NAME, "Dark areas in the recorded video (issue 25)", body, quick=args.quick, started=started)


if __name__ == "__main__":
    main()
