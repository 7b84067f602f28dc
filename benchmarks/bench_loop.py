"""Edit → verdict on the reference design (issue 28): wall and CPU seconds from saving mount.toml to
`compare`'s 99 % verdict at 5 % tolerance, (a) through `lensmount watch` and (b) through the plain
commands (`regenerate`, then `compare --against last --until-decided --quick`).

    python benchmarks/bench_loop.py [--workdir DIR] [--baseline-passes 8] [--skip watch|plain]

A copy of examples/double-gauss-360 in a git repository, regenerated, and its case-2 run (the
previous revision, --baseline-passes passes of the scene's photons) in a store of its own: that
setup is not timed. The edit removes the hood's vanes (`[vanes] count = 0`, about +20 % on case 2):
the verdict must be a regression (exit 1). Each variant starts from the same store (a copy taken
after the baseline), so neither finds the other's run of the edited design. The simulations run
niced; the machine's load average is printed before and after (the machine may be shared: CPU
seconds are the figure that does not depend on it). Also: `lensmount --help` (the CLI's start-up)
and the new run's phases from its summary.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "double-gauss-360"
SCENE = "case2-lambertian"
LM = [str(Path(sys.executable).parent / "lensmount")]  # the console script, as a user runs it
NICE = ["nice", "-n", "10"]


def load() -> str:
    return "load " + " ".join(f"{x:.1f}" for x in os.getloadavg())


def children_cpu() -> float:
    r = os.times()
    return r.children_user + r.children_system


def run(args: list[str], env: dict, **kw) -> tuple[subprocess.CompletedProcess, float, float]:
    """(result, wall s, CPU s of the command and its children)."""
    cpu, t = children_cpu(), time.perf_counter()
    done = subprocess.run(NICE + LM + args, env=env, capture_output=True, text=True, **kw)
    return done, time.perf_counter() - t, children_cpu() - cpu


def setup(root: Path, env: dict, passes: int) -> Path:
    design = root / "design"
    shutil.copytree(EXAMPLE, design, ignore=shutil.ignore_patterns("build", ".lensmount", "out"))
    git = ["git", "-C", str(design), "-c", "user.email=bench@lensmount", "-c", "user.name=bench"]
    subprocess.run(["git", "init", "-q", str(design)], check=True)
    subprocess.run(git + ["add", "-A"], check=True)
    subprocess.run(git + ["commit", "-qm", "the previous revision"], check=True)
    done, wall, cpu = run(["regenerate", str(design)], env)
    assert done.returncode == 0, done.stderr
    print(f"setup: regenerate {wall:.1f} s wall, {cpu:.1f} s CPU")
    done, wall, cpu = run(["simulate", str(design), "--scene", str(design / "scenes" / f"{SCENE}.toml"),
                           "--passes", str(passes), "--out", str(root / "baseline")], env)
    assert done.returncode == 0, done.stderr
    s = json.loads((root / "baseline" / "summary.json").read_text())
    print(f"setup: baseline case 2, {s['passes']} passes × {s['photons_per_pass']:,}: {s['stray_fraction']:.4g} "
          f"± {100 * s['stray_fraction_rel_error']:.2f} % (std + bias), {wall:.0f} s wall, {cpu:.0f} s CPU, {load()}")
    return design


def remove_vanes(design: Path) -> None:
    mount = design / "mount.toml"
    text = mount.read_text()
    edited = re.sub(r"(?m)^count = 3\b", "count = 0", text, count=1)
    assert edited != text, "mount.toml has no [vanes] count = 3"
    mount.write_text(edited)


def restore(design: Path, store: Path, clean_store: Path, env: dict) -> None:
    """The design at the previous revision, built, the store as it was after the baseline, and no run nor
    CAD cache of the edit (regenerate's cache would otherwise hand the next variant the edited mount)."""
    subprocess.run(["git", "-C", str(design), "checkout", "-q", "--", "mount.toml"], check=True)
    shutil.rmtree(design / "build")
    done, _, _ = run(["regenerate", str(design)], env)
    assert done.returncode == 0, done.stderr
    shutil.copy2(clean_store, store)
    for p in (design / ".lensmount" / "runs").glob("*") if (design / ".lensmount" / "runs").is_dir() else ():
        shutil.rmtree(p)
    shutil.rmtree(design / ".lensmount" / "watch", ignore_errors=True)


def phases(design: Path) -> str:
    """The newest simulated run of the edited design: its phases (wall) and passes."""
    runs = sorted((design / ".lensmount" / "runs").glob("*/summary.json"), key=lambda p: p.stat().st_mtime)
    if not runs:
        return "no run simulated"
    s = json.loads(runs[-1].read_text())
    wall = ", ".join(f"{k} {v:.1f} s" for k, v in s["plan"].get("wall_time_s", {}).items())
    cpu = ", ".join(f"{k.removesuffix(', CPU')} {v:.1f} s" for k, v in s["plan"]["time_s"].items() if k.endswith("CPU"))
    return (f"new run: {s['passes']} passes, {100 * s['stray_fraction_rel_error']:.2f} %; wall: {wall}; "
            f"CPU by phase (summed over workers): {cpu}")


def plain(design: Path, env: dict) -> None:
    print(f"(b) plain commands, {load()}")
    remove_vanes(design)
    t, total_cpu = time.perf_counter(), 0.0
    for args in (["regenerate", str(design)],
                 ["compare", str(design), "--scene", SCENE, "--against", "last", "--until-decided", "--quick"]):
        done, wall, cpu = run(args, env)
        total_cpu += cpu
        print(f"  lensmount {args[0]}: exit {done.returncode}, {wall:.1f} s wall, {cpu:.1f} s CPU")
        if args[0] == "compare":
            verdict = [line for line in done.stdout.splitlines() if line.startswith("verdict:")]
            print("  " + (verdict[0] if verdict else done.stdout[-600:] + done.stderr[-600:]))
            assert done.returncode == 1, "expected a regression (exit 1)"
    print(f"  edit → verdict (plain): {time.perf_counter() - t:.1f} s wall, {total_cpu:.1f} s CPU; {load()}")
    print("  " + phases(design))


def proc_cpu(pid: int) -> float:
    """CPU seconds of a process and its reaped children (utime, stime, cutime, cstime)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def watched(design: Path, env: dict) -> None:
    print(f"(a) watch, {load()}")
    t = time.perf_counter()
    proc = subprocess.Popen(NICE + LM + ["watch", str(design), "--scene", SCENE], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines: list[tuple[float, str]] = []
    ready, judged = threading.Event(), threading.Event()

    def read(stream, mark, event):
        for line in stream:
            lines.append((time.perf_counter(), line.rstrip()))
            if mark in line:
                event.set()

    threading.Thread(target=read, args=(proc.stderr, "baseline ready", ready), daemon=True).start()
    threading.Thread(target=read, args=(proc.stdout, "revision 1", judged), daemon=True).start()
    try:
        if not ready.wait(1200):
            raise SystemExit("watch: no baseline in 20 min:\n" + "\n".join(x for _, x in lines[-20:]))
        print(f"  watch start-up and baseline: {time.perf_counter() - t:.1f} s (paid once)")
        time.sleep(1.0)  # the first snapshot is taken
        cpu, t = proc_cpu(proc.pid), time.perf_counter()
        remove_vanes(design)
        if not judged.wait(1200):
            raise SystemExit("watch: no verdict in 20 min:\n" + "\n".join(x for _, x in lines[-20:]))
        wall, cpu = time.perf_counter() - t, proc_cpu(proc.pid) - cpu
        print("  " + next(x for _, x in lines if "revision 1" in x))
        assert "regression:" in next(x for _, x in lines if "revision 1" in x), "expected a regression"
        print(f"  edit → verdict (watch): {wall:.1f} s wall, {cpu:.1f} s CPU; {load()}")
        print("  " + phases(design))
    finally:
        proc.terminate()
        proc.wait(60)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workdir", type=Path, help="Keep the design, runs and store here (default: a temp dir).")
    parser.add_argument("--baseline-passes", type=int, default=8)
    parser.add_argument("--skip", choices=("watch", "plain"))
    args = parser.parse_args()
    root = args.workdir or Path(tempfile.mkdtemp(prefix="bench-loop-"))
    root.mkdir(parents=True, exist_ok=True)
    store = root / "runs.sqlite"
    env = {**os.environ, "LENSMOUNT_STORE": str(store), "PYTHONPATH": os.pathsep.join(
        filter(None, [str(Path(__file__).resolve().parents[1] / "src"), os.environ.get("PYTHONPATH")]))}
    print(f"bench_loop in {root}, {load()}, {os.cpu_count()} cores")
    done, wall, cpu = run(["--help"], env)
    print(f"lensmount --help (start-up): {wall:.1f} s wall, {cpu:.1f} s CPU")
    design = setup(root, env, args.baseline_passes)
    clean = root / "runs-after-baseline.sqlite"
    shutil.copy2(store, clean)
    if args.skip != "watch":
        watched(design, env)
        restore(design, store, clean, env)
    if args.skip != "plain":
        plain(design, env)
        restore(design, store, clean, env)


if __name__ == "__main__":
    main()
