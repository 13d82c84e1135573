#!/usr/bin/env python3
"""`splatbridge.render` from Python against the CLI's `splatbridge bench render`, one run.

The Python package promises native renders within 5 % of `bench render`'s median frame time
(the same renderer, scene and camera). Both sides get one untimed warm-up render, then
`--repeat` timed renders; the rounds alternate (CLI, Python, CLI, ...) so that a load change
on the shared machine hits both. Printed: each side's median over all its renders, the ratio
Python / CLI, and the load average at the start and the end.

Usage (release wheel installed in the environment, release CLI):
    target/py-venv/bin/python scripts/python-bench.py SCENE [--cli target/release/splatbridge]
        [--camera orbit:4:1] [--width 1920] [--height 1080] [--repeat 5] [--rounds 3]
"""

import argparse
import json
import os
import statistics
import subprocess
import time

import splatbridge


def cli_medians(args):
    cmd = [
        args.cli, "bench", "render", args.scene, "--camera", args.camera,
        "--width", str(args.width), "--height", str(args.height),
        "--repeat", str(args.repeat), "--json",
    ]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out)["median_frame_ms"]


def python_times(scene, args):
    # The camera resolved once, as `bench render` resolves it before its loop (an orbit spec
    # frames the scene's Gaussians, a pass over the cloud a render loop need not repeat).
    cam = scene.camera(args.camera, args.width, args.height)
    splatbridge.render(scene, cam)  # warm-up
    times = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        splatbridge.render(scene, cam)
        times.append((time.perf_counter() - t0) * 1e3)
    return times


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("--cli", default="target/release/splatbridge")
    p.add_argument("--camera", default="orbit:4:1")
    p.add_argument("--width", type=int, default=1920)
    p.add_argument("--height", type=int, default=1080)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    load0 = os.getloadavg()[0]
    scene = splatbridge.load(args.scene)
    cli, py = [], []
    for _ in range(args.rounds):
        # The CLI reports only its median per run; each run's median stands for its repeats.
        cli += [cli_medians(args)] * args.repeat
        py += python_times(scene, args)
    c, q = statistics.median(cli), statistics.median(py)
    print(f"scene {args.scene}, camera {args.camera} {args.width}x{args.height}, "
          f"{args.rounds} rounds x {args.repeat} renders")
    print(f"bench render (CLI) median {c:.1f} ms")
    print(f"splatbridge.render  median {q:.1f} ms (min {min(py):.1f}, max {max(py):.1f})")
    print(f"ratio Python / CLI {q / c:.3f}")
    print(f"load average {load0:.1f} -> {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
