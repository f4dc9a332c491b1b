"""``usdmotion render IN OUT``: offscreen feedback video (.mp4) or image sequence (####.png/.exr/.jpg)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, ReadOptions, parse_start_stop, reads_motion
from usdmotion.cli._progress import progress
from usdmotion.cli.app import app

Opt = typer.Option


@app.command()
@reads_motion
def render(
    source: InputPath,
    output: Annotated[Path, typer.Argument(help="Video (.mp4) or image sequence pattern (frames/####.png, "
                                                ".jpg, .exr = linear floats).", show_default=False)],
    size: Annotated[str, Opt(help="Image size WIDTHxHEIGHT.")] = "1280x720",
    frames: Annotated[str | None, Opt(help="Source frame range START:STOP (stop exclusive).")] = None,
    fps: Annotated[float | None, Opt(help="Output frame rate (default: the motion's, at most 60).")] = None,
    speed: Annotated[float, Opt(help="Playback speed (0.25 = 4x slow motion).")] = 1.0,
    camera: Annotated[str, Opt(help="Preset (side, front, top, follow, orbit) or a USD camera: "
                                    "cam.usda[:/Path/To/Camera].")] = "side",
    style: Annotated[str, Opt(help="body, stick or both (a translucent body around the stick figure).")] = "body",
    focus: Annotated[str | None, Opt(help="Joints the camera preset frames, comma-separated (a close-up: "
                                          "--focus Foot_L,Toes_L); default the whole body.")] = None,
    body: Annotated[str, Opt(help="auto (the input's own skinned mesh if it has one), stage or generated "
                                  "(usdmotion's capsule body).")] = "auto",
    grid: Annotated[bool, Opt(help="Draw the ground grid.")] = True,
    grid_scale: Annotated[float, Opt(help="Grid spacing in metres.")] = 1.0,
    trace: Annotated[list[str] | None, Opt(help="Joint name or 'com' whose path to draw (repeatable).")] = None,
    overlay: Annotated[bool, Opt(help="Frame/time text overlay.")] = True,
    angle: Annotated[list[str] | None, Opt(help="Angle to draw with its value (repeatable): knee_left, elbow_right, "
                                                "hip_left, shoulder_right, ankle_left, wrist_right, trunk, or A,B,C "
                                                "(at B). Values also go to OUT.angles.json.")] = None,
    layout: Annotated[str | None, Opt(help="Several synchronised views ROWSxCOLUMNS, one --camera each: "
                                           "--layout 2x2 --camera side,front,top,follow.")] = None,
    panel: Annotated[str | None, Opt(help="Plot strip under the picture with a time cursor: angle:NAME and/or "
                                          "speed:JOINT, comma-separated (angle:knee_left,speed:RightHand).")] = None,
    strobe: Annotated[int | None, Opt(help="Stroboscope still: N poses over the range in one picture "
                                           "(OUT is one .png/.jpg).")] = None,
    strobe_every: Annotated[str | None, Opt(help="Stroboscope still with a pose every TIME: 0.1s, 100ms or "
                                                 "12f.")] = None,
    compare: Annotated[Path | None, Opt(help="A second motion to compare with.")] = None,
    compare_mode: Annotated[str, Opt(help="ghost (overlaid, translucent) or side (side by side).")] = "ghost",
    align: Annotated[str, Opt(help="How --compare's clock maps: start (same seconds), time (DTW on bone angles) "
                                   "or frame:N,M (frame N shows with OTHER's frame M); OTHER is also moved onto "
                                   "the main take's root and heading.")] = "start",
    contact_shadow: Annotated[bool, Opt(help="Soft shadow disc on the ground under the body.")] = True,
    shadows: Annotated[bool, Opt(help="Shadows from the key light (about half the speed).")] = False,
    msaa: Annotated[int, Opt(help="Multisample anti-aliasing samples (0 = off: the --fxaa pass instead; 4 is "
                                  "about half the speed on a CPU).")] = 0,
    fxaa: Annotated[bool, Opt(help="Anti-alias edges with one FXAA pass when --msaa is 0 (cheap on a CPU).")] = True,
    quality: Annotated[int, Opt(help="H.264 CRF (lower = better, larger).")] = 20,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Render a motion offscreen to a video or image sequence (skinned body, stick figure)."""
    from usdmotion.render import RenderOptions, check_options, output_frames, render_motion
    from usdmotion.render.output import check_output

    width, height = _size(size)
    start, end = parse_start_stop(frames)
    options = RenderOptions(width=width, height=height, start=start, end=end, fps=fps, speed=speed, camera=camera,
                            style=style, grid=grid, grid_scale=grid_scale, traces=tuple(trace or ()),
                            overlay=overlay, compare_mode=compare_mode, shadows=shadows, msaa=msaa, fxaa=fxaa, quality=quality,
                            labels=(source.name, compare.name if compare else ""), angles=tuple(angle or ()),
                            align=align, panel=panel, layout=layout, contact_shadow=contact_shadow, body=body,
                            focus=tuple(n.strip() for n in focus.split(",") if n.strip()) if focus else ())
    check_options(options)  # every option before any work
    if strobe is None and strobe_every is None:
        check_output(output, width, height)
    motion = read.read(source)
    other = read.read(compare) if compare else None
    if strobe is not None or strobe_every is not None:
        from usdmotion.render.strobe import render_strobe

        if other is not None:
            raise ValueError("--strobe draws one take: leave out --compare")
        unused = [name for name, given in (("--angle", angle), ("--panel", panel), ("--layout", layout)) if given]
        if unused:
            raise ValueError(f"--strobe draws poses and traces only: leave out {', '.join(unused)}")
        shown = render_strobe(motion, output, options, strobe, strobe_every)
        typer.echo(f"wrote {output}: {len(shown)} poses, frames {shown[0]}-{shown[-1]}, {width}x{height}")
        return
    total = len(output_frames(motion, options)[0])
    with progress(f"rendering {output.name}", total=total, unit="frames") as update:
        result = render_motion(motion, output, options, other, progress=update)
    t = result.timings
    typer.echo(f"wrote {output}: {result.frames} frames {width}x{height} in {result.seconds:.1f} s "
               f"({result.fps:.1f} frames/s; body {t.get('build', 0):.1f} s, rendering {t.get('render', 0):.1f} s; "
               f"in parallel: skinning {t.get('skin', 0):.1f} s, overlays {t.get('overlay', 0):.1f} s, "
               f"encoding {t.get('encode', 0):.1f} s)")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: {text!r} is not WIDTHxHEIGHT, e.g. 1280x720") from None
    return w, h


