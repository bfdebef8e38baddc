#!/usr/bin/env python3
"""make bench: the random booth x head matrix, reconstructed by `facescan recon` and by the stock
OpenCV SGBM baseline (build/bin/sgbm-baseline) on the same capture in the same run, both scored
against the simulator's ground truth; writes docs/benchmarks.md. The issue's completeness and
vertex floors are judged on `facescan evaluate`'s face figures (ground_truth_face.ply: hairline to
chin, ear to ear); the whole head's are shown beside them.

Usage: tools/bench.py BIN_DIR [--booths N] [--heads K] [--first-seed S] [--out FILE]
Environment: BENCH_DIR (work directory, default build/bench), BENCH_BOOTHS, BENCH_HEADS.
"""
import argparse
import datetime
import hashlib
import json
import os
import resource
import statistics
import subprocess
import sys
import time

# The floors. Completeness and vertices are over the face (hairline to chin, ear to ear:
# the set's ground_truth_face.ply), not the whole head `facescan evaluate` also reports.
FLOORS = {"rms_mm": 0.30, "face_completeness": 0.85, "face_region_vertices": 100000, "time_ratio": 0.5, "peak_mb": 600}


def run_measured(cmd, log):
    """Runs cmd as a child; returns (wall seconds, CPU seconds, the child's peak RSS in MB)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        return None, None, None
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    # ru_maxrss of RUSAGE_CHILDREN is the largest child so far: run each measured command in a
    # fresh python child so the figure is this command's own.
    return wall, cpu, max(after.ru_maxrss, before.ru_maxrss) / 1024.0


def measured(cmd, log):
    """wall, CPU seconds, peak MB of one command, each in its own process tree (see run_measured)."""
    probe = subprocess.run([sys.executable, __file__, "--measure", log, "--"] + cmd,
                           capture_output=True, text=True)
    if probe.returncode != 0:
        return None, None, None
    wall, cpu, mb = probe.stdout.split()
    return float(wall), float(cpu), float(mb)


def simulator_stamp():
    """A hash of the sources a rendered set depends on (simulator, pattern, capture writer): a set
    rendered by another version of them is rendered again, not reused."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    h = hashlib.sha256()
    for top in ("tools/sim", "host/pattern", "host/capture"):
        for dirpath, _, files in sorted(os.walk(os.path.join(root, top))):
            for name in sorted(files):
                path = os.path.join(dirpath, name)
                h.update(os.path.relpath(path, root).encode())
                with open(path, "rb") as f:
                    h.update(f.read())
    return h.hexdigest()


def evaluate(fs, mesh, capture, out_json):
    r = subprocess.run([fs, "evaluate", mesh, capture, "--json", out_json], capture_output=True, text=True)
    if r.returncode != 0:
        return None
    with open(out_json) as f:
        return json.load(f)


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--measure":
        log, cmd = sys.argv[2], sys.argv[4:]
        wall, cpu, mb = run_measured(cmd, log)
        if wall is None:
            sys.exit(1)
        print(wall, cpu, mb)
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("bin")
    ap.add_argument("--booths", type=int, default=int(os.environ.get("BENCH_BOOTHS", 12)))
    ap.add_argument("--heads", type=int, default=int(os.environ.get("BENCH_HEADS", 3)))
    ap.add_argument("--first-seed", type=int, default=101)
    ap.add_argument("--out", default="docs/benchmarks.md")
    # One more scene per booth with the scanned head (`--head scan`, a real head's CT fetched by
    # tools/install-web-deps.sh scan; docs/simulator.md), where it was fetched.
    ap.add_argument("--scan-head", type=int, default=int(os.environ.get("BENCH_SCAN_HEAD", 1)))
    a = ap.parse_args()
    fs = os.path.join(a.bin, "facescan")
    base = os.path.join(a.bin, "sgbm-baseline")
    work = os.environ.get("BENCH_DIR", "build/bench")
    os.makedirs(work, exist_ok=True)
    rows = []
    stamp = simulator_stamp()
    # Where `facescan simulate --head scan` looks (tools/sim/simulate_verb.cpp, scan_head_dir).
    scan_dir = os.environ.get("FACESCAN_SCAN_HEAD") or os.path.join(os.path.dirname(os.path.abspath(a.bin)), "cache", "scan-head")
    a.scan = a.scan_head and os.path.exists(os.path.join(scan_dir, "volume.raw"))
    if a.scan_head and not a.scan:
        print("bench: no scanned head in %s (tools/install-web-deps.sh scan): its rows are left out" % scan_dir, flush=True)
    for b in range(a.booths):
        booth = a.first_seed + b
        heads = [("random", booth * 10 + k) for k in range(a.heads)] + ([("scan", booth * 10 + 9)] if a.scan else [])
        for kind, head in heads:
            name = "booth%d-%s%d" % (booth, "head" if kind == "random" else "scan", head)
            cap = os.path.join(work, name)
            # A set rendered by an earlier run of the same simulator sources is reused
            # (BENCH_FRESH=1: never).
            stamp_path = os.path.join(cap, "bench-simulator-stamp")
            old_stamp = open(stamp_path).read() if os.path.exists(stamp_path) else ""
            if (os.environ.get("BENCH_FRESH") != "1" and old_stamp == stamp
                    and os.path.exists(os.path.join(cap, "ground_truth.ply"))):
                print("bench: %s: reusing the rendered set" % name, flush=True)
            else:
                subprocess.run(["rm", "-rf", cap], check=True)
                print("bench: %s: simulate" % name, flush=True)
                r = subprocess.run([fs, "simulate", "--booth", "random", "--seed", str(booth), "--head", kind,
                                    "--head-seed", str(head), "--out", cap], capture_output=True, text=True)
                if r.returncode != 0:
                    print("bench: %s: simulate failed: %s" % (name, r.stderr.strip()), file=sys.stderr)
                    sys.exit(1)
                with open(stamp_path, "w") as f:
                    f.write(stamp)
            row = {"name": name, "booth": booth, "head": head}
            drc, rep = cap + ".drc", cap + ".json"
            row["recon_s"], row["recon_cpu"], row["peak_mb"] = measured([fs, "recon", cap, "-o", drc, "--report", rep], cap + "-recon.log")
            row["base_s"], row["base_cpu"], row["base_peak_mb"] = measured([base, cap, "-o", cap + "-sgbm.drc"], cap + "-sgbm.log")
            row["recon"] = evaluate(fs, drc, cap, cap + "-eval.json") if row["recon_s"] else None
            row["base"] = evaluate(fs, cap + "-sgbm.drc", cap, cap + "-sgbm-eval.json") if row["base_s"] else None
            if row["recon_s"]:
                with open(rep) as f:
                    row["report"] = json.load(f)
            rows.append(row)
            e = row["recon"] or {}
            print("bench: %s: recon %s s, RMS %.3f mm, face completeness %s, %s face vertices (whole head %s, %s); "
                  "sgbm %s s" % (
                      name, row["recon_s"], e.get("rms_mm", float("nan")),
                      fmt(pct(e.get("face_completeness")), "%.1f %%", "—" if e else "failed"),
                      fmt(e.get("face_region_vertices"), "%d", "—" if e else "failed"), fmt(pct(e.get("completeness")), "%.1f %%"),
                      fmt(e.get("face_vertices"), "%d"), row["base_s"]), flush=True)
    write(a.out, rows, a)


def fmt(x, spec, missing="failed"):
    return spec % x if x is not None else missing


def pct(x):
    return 100 * x if x is not None else None


def face_coverage(e):
    """How much of the face the booth counts at all (seen by >= 2 cameras and lit), whatever the
    reconstruction: face_counted / face_truth_points; None for a set without a face."""
    if not e or not e.get("face_truth_points"):
        return None
    return e["face_counted"] / e["face_truth_points"]


def face(e, key):
    """A face figure of an evaluation, None where the evaluation failed or the set has no face."""
    return e.get(key) if e else None


def write(path, rows, a):
    ok = [r for r in rows if r["recon"]]
    lines = []
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(l.split(":", 1)[1].strip() for l in f if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    lines += ["# Benchmarks", "",
              "Generated by `make bench` (tools/bench.py) on %s, %d cores (%s), release build." % (
                  datetime.date.today().isoformat(), os.cpu_count() or 0, cpu), "",
              "Every scene is a random booth and a random head from the simulator's documented ranges",
              "(`facescan simulate --booth random --seed B --head random --head-seed H`, docs/simulator.md):",
              "cameras, lenses, projectors (pitch on the face 6-20 mm, any quarter turn and roll, overlapping",
              "or masked to zones), light, noise, the head's pose, its shape and appearance, and an error of a",
              "good calibration (~0.3 px) in the calibration the reconstruction is given. %d booths x %d heads%s," % (
                  a.booths, a.heads, " + the scanned head (rows `boothB-scanH`: `--head scan --head-seed H`, a real" +
                  " head's CT, crown to upper lip, with a random head's skin; docs/simulator.md)" if a.scan else ""),
              "booth seeds from %d. Each capture is reconstructed by `facescan recon` (dense, the default) and by" % a.first_seed,
              "the stock OpenCV pipeline (`build/bin/sgbm-baseline`: stereoRectify, SGBM 3-way at half resolution",
              "over the working volume's disparities, its left-right check and speckle filter, no decoding) in",
              "the same run. Times are wall seconds of the whole command (reading the PNGs included), peak",
              "memory the command's maximum resident set.", "",
              "The issue's floors are over the **face** (hairline to chin, ear to ear: the simulator's",
              "`face_region()`, written as each set's `ground_truth_face.ply`), so they are judged on the face",
              "figures: **face completeness** is the fraction of the face's truth points the booth counts (seen",
              "by >= 2 cameras and lit by a projector) that lie within 1 mm of the mesh, **face vertices** the",
              "mesh's distinct vertex positions within ~2 mm of a face point (counted or not: a vertex on the",
              "face is on it where the visibility test gives up too); **face coverage** is how much of the",
              "face the booth counts at all (counted / all face points: what no reconstruction can win back).",
              "**Head completeness** and **head vertices** are the same figures over every counted truth point",
              "of the head (neck, ears, scalp and shoulders too: what this table's completeness and face",
              "vertices were before), kept beside them for comparison; no floor is judged on them. RMS, median",
              "and p95 are over every distinct vertex position of the mesh. `—`: the set has no",
              "`ground_truth_face.ply` (rendered before the simulator wrote it).", "",
              "Reproduce one row: `build/bin/facescan simulate --booth random --seed B --head random --head-seed H",
              "--out /tmp/s && build/bin/facescan recon /tmp/s -o /tmp/s.drc && build/bin/facescan evaluate /tmp/s.drc /tmp/s`.", "",
              "| scene | RMS mm | median | p95 | face completeness | face vertices | face coverage | head completeness | head vertices | recon s (CPU s) | SGBM s (CPU s) | time ratio | peak MB | SGBM RMS | SGBM face completeness | SGBM face vertices |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        e, b = r["recon"] or {}, r["base"] or {}
        ratio = r["recon_s"] / r["base_s"] if r["recon_s"] and r["base_s"] else None
        r["ratio"] = ratio
        # A failed evaluation says "failed"; a figure the set cannot give (no face) says "—".
        nf = "failed" if not e else "—"
        nb = "failed" if not b else "—"
        lines.append("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["name"], fmt(e.get("rms_mm"), "%.3f"), fmt(e.get("median_mm"), "%.3f"), fmt(e.get("p95_mm"), "%.3f"),
            fmt(pct(e.get("face_completeness")), "%.1f %%", nf), fmt(e.get("face_region_vertices"), "%d", nf),
            fmt(pct(face_coverage(e or b)), "%.1f %%", "failed" if not (e or b) else "—"),
            fmt(pct(e.get("completeness")), "%.1f %%"), fmt(e.get("face_vertices"), "%d"),
            fmt(r["recon_s"], "%.2f") + " (" + fmt(r["recon_cpu"], "%.2f") + ")",
            fmt(r["base_s"], "%.2f") + " (" + fmt(r["base_cpu"], "%.2f") + ")", fmt(ratio, "%.2f"), fmt(r["peak_mb"], "%.0f"),
            fmt(b.get("rms_mm"), "%.3f"), fmt(pct(b.get("face_completeness")), "%.1f %%", nb),
            fmt(b.get("face_region_vertices"), "%d", nb)))
    lines += ["", "## Distribution and worst rows", "",
              "| figure | floor | min | median | max | worst scene | scenes meeting the floor |", "|---|---|---|---|---|---|---|"]

    def dist(label, floor, key, higher_better, scale=1.0, spec="%.3f"):
        """One figure's row; floor None: shown for comparison, no floor judged on it."""
        vals = [(key(r), r["name"]) for r in rows if key(r) is not None]
        if not vals:
            if floor is not None:  # a floor no scene could be judged on is said, not dropped
                lines.append("| %s | %s %s | — | — | — | — | 0 / %d (no scene has the figure) |" % (
                    label, ">=" if higher_better else "<=", spec % (floor * scale), len(rows)))
            return
        xs = [v for v, _ in vals]
        worst = min(vals) if higher_better else max(vals)
        if floor is None:
            floor_text, meets_text = "—", "—"
        else:
            floor_text = "%s %s" % (">=" if higher_better else "<=", spec % (floor * scale))
            meets = sum(1 for v in xs if (v >= floor if higher_better else v <= floor))
            meets_text = "%d / %d" % (meets, len(rows))
        lines.append("| %s | %s | %s | %s | %s | %s | %s |" % (
            label, floor_text, spec % (min(xs) * scale), spec % (statistics.median(xs) * scale),
            spec % (max(xs) * scale), worst[1], meets_text))

    dist("vertex RMS (mm)", FLOORS["rms_mm"], lambda r: r["recon"] and r["recon"]["rms_mm"], False)
    dist("face completeness within 1 mm (%)", FLOORS["face_completeness"],
         lambda r: face(r["recon"], "face_completeness"), True, 100, "%.1f")
    dist("vertices on the face", FLOORS["face_region_vertices"], lambda r: face(r["recon"], "face_region_vertices"),
         True, 1, "%d")
    dist("face coverage: face points the booth counts (%)", None, lambda r: face_coverage(r["recon"] or r["base"]),
         True, 100, "%.1f")
    dist("head completeness within 1 mm (%), for comparison", None,
         lambda r: r["recon"] and r["recon"]["completeness"], True, 100, "%.1f")
    dist("vertices on the counted head, for comparison", None, lambda r: r["recon"] and r["recon"]["face_vertices"],
         True, 1, "%d")
    dist("recon time / SGBM time (wall)", FLOORS["time_ratio"], lambda r: r.get("ratio"), False, 1, "%.2f")
    dist("recon CPU / SGBM CPU", FLOORS["time_ratio"],
         lambda r: r["recon_cpu"] / r["base_cpu"] if r.get("recon_cpu") and r.get("base_cpu") else None, False, 1, "%.2f")
    dist("peak memory (MB)", FLOORS["peak_mb"], lambda r: r["peak_mb"], False, 1, "%.0f")
    failed = [r["name"] for r in rows if not r["recon"]]
    if failed:
        lines += ["", "Reconstruction failed on: " + ", ".join(failed)]
    # Mean stage times over the scenes (ms).
    stages = {}
    for r in ok:
        for k, v in r.get("report", {}).get("time_ms", {}).items():
            stages.setdefault(k, []).append(v)
    if stages:
        lines += ["", "Mean stage times over the scenes (ms, from the recon reports): " + ", ".join(
            "%s %.0f" % (k, statistics.mean(v)) for k, v in stages.items()) + "."]
    lines += ["", "What limits each figure: docs/recon.md, \"Limits\"."]
    with open(path + ".tmp", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(path + ".tmp", path)
    print("bench: wrote %s" % path)


if __name__ == "__main__":
    main()
