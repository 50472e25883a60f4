#!/usr/bin/env python3
"""The start of a run from one Gmsh file, phase by phase: what the first rank does alone
while the others wait (the scan of the file, the assembly of the shares, the problem,
the partition and split, the scatter), on one core and on all of its node's cores.

    python3 run-scripts/start_study.py CASE.toml [CASE.toml ...] --out DIR \\
        [--ranks 2] [--runs 3] [--partitioner auto|metis|ptscotch]
        [--binary target/release/contact-par]

Each case runs on --ranks ranks with `--mesh-read shared` (every rank parses a share of
the file), alternately `--bind-to core --borrow-idle-cores false` (the first rank has
one core for its work alone) and `--bind-to none` (it borrows the cores of the ranks of
its node), --runs
times each; the medians go to DIR/start.csv and a table on stdout. `serial share` is the
first rank's seconds alone over the whole run's. With `--partitioner ptscotch` the
cut is made by every rank (from their shares of the file) while the first rank puts the
mesh together and builds the problem: the cut's seconds, named on the partition line,
are not the first rank's alone, and of the assembly and the problem only the seconds
they went on after the cut (`read_after_s`, also on the partition line) are; nor are
those of the parts that each rank then builds for itself (`ranks_build_s`, "parts built
on their ranks" on the partition line). Where the ranks build their own parts, the first
rank no longer puts the mesh together nor builds the whole problem: every rank checks
the mesh on its parts and finds the conditions of the groups' nodes (`checks_s`, "checked
and its conditions found on the ranks" on the read line; not the first rank's alone),
and its assembly and problem are zero.

With --split-parts (e.g. 2,64,512), `contact-par split --parts P` also runs on one core
(read, problem, partition into P parts, the part files written): its seconds and peak
memory on one process holding the whole mesh, against P, to DIR/split.csv.
run-scripts/cost_model.py `--start DIR` fits its laws to both CSV files and predicts the
start of a larger run.
"""
import argparse
import csv
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

READ = re.compile(
    r"^read\s+done in\s+([\d.]+) s: .*?: (\d+) nodes, (\d+) triangles.*?"
    r"mesh read on \d+ ranks in ([\d.]+) s \(the first rank alone ([\d.]+) s: "
    r"case, file and scan ([\d.]+) s, assembly ([\d.]+) s\), problem ([\d.]+) s"
)
# Where the ranks cut the file from their shares and the first rank builds only the
# conditions, no rank holding the whole mesh: no assembly or problem on the first rank,
# the checks and the conditions found by every rank.
READ_GROUPS = re.compile(
    r"^read\s+done in\s+([\d.]+) s: .*?: (\d+) nodes, (\d+) triangles.*?"
    r"mesh read on \d+ ranks in ([\d.]+) s \(the first rank alone ([\d.]+) s: "
    r"case, file and scan\), checked and its conditions found on the ranks in ([\d.]+) s"
)
PHASE = re.compile(r"^(\w+)\s+done in\s+([\d.]+) s")
RANKS_CUT = re.compile(r"^partition done in .*?, cut ([\d.]+) s \(PT-Scotch on ")
READ_AFTER = re.compile(r"which went on ([\d.]+) s longer")
RANKS_BUILD = re.compile(r"parts built on their ranks ([\d.]+) s")
TOTAL = re.compile(r"^total\s+([\d.]+)")

FIELDS = [
    "case", "nodes", "triangles", "ranks", "bind", "cores", "runs",
    "scan_s", "shares_s", "assembly_s", "problem_s", "partition_s", "ranks_cut_s", "ranks_build_s",
    "read_after_s", "checks_s", "scatter_s",
    "alone_s", "total_s", "serial_share", "rank0_peak_bytes", "other_peak_bytes",
]


def one_run(binary, case, ranks, bind, out, partitioner):
    if bind == "core" and (os.cpu_count() or 1) < ranks:
        # Open MPI refuses to bind more ranks than cores: the one-core figures are then
        # the unbound ones, and the fitted threaded shares zero.
        bind = "none"
    cmd = [
        "mpirun", "-n", str(ranks), "--oversubscribe", "--bind-to", bind,
        binary, case, "--mesh-read", "shared", "--threads", "1", "--no-plots",
        "--out", out, "--partitioner", partitioner,
        # Ranks bound to their cores lend them too unless told not to.
        "--borrow-idle-cores", "false" if bind == "core" else "true",
    ]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"start_study: {' '.join(cmd)} failed:\n{p.stderr}")
    row = {"ranks_cut_s": 0.0, "ranks_build_s": 0.0, "read_after_s": None, "checks_s": 0.0}
    for line in p.stdout.splitlines():
        m = RANKS_CUT.match(line)
        if m:
            row["ranks_cut_s"] = float(m.group(1))
        m = READ_AFTER.search(line)
        if m:
            row["read_after_s"] = float(m.group(1))
        m = RANKS_BUILD.search(line)
        if m:
            row["ranks_build_s"] = float(m.group(1))
        m = READ.match(line)
        if m:
            _, nodes, tris, together, alone, scan, assembly, problem = m.groups()
            row.update(
                nodes=int(nodes), triangles=int(tris), scan_s=float(scan),
                assembly_s=float(assembly), problem_s=float(problem),
                # The shares: every rank parses its own; the gathers.
                shares_s=float(together) - float(alone),
            )
            continue
        m = READ_GROUPS.match(line)
        if m:
            _, nodes, tris, together, alone, checks = m.groups()
            row.update(
                nodes=int(nodes), triangles=int(tris), scan_s=float(alone),
                assembly_s=0.0, problem_s=0.0, checks_s=float(checks),
                shares_s=float(together) - float(alone),
            )
            continue
        m = PHASE.match(line)
        if m and m.group(1) in ("partition", "scatter"):
            row[m.group(1) + "_s"] = float(m.group(2))
        m = TOTAL.match(line)
        if m:
            row["total_s"] = float(m.group(1))
    if "scan_s" not in row:
        sys.exit(f"start_study: {case}: the read line does not name a shared read "
                 "(an MSH 4.1 file is needed)")
    with open(os.path.join(out, "summary.json")) as f:
        peaks = json.load(f)["peak_memory_bytes_per_rank"]
    row["rank0_peak_bytes"] = peaks[0]
    row["other_peak_bytes"] = statistics.median(peaks[1:]) if len(peaks) > 1 else 0
    if row["read_after_s"] is None:
        row["read_after_s"] = row["assembly_s"] + row["problem_s"]
    row["alone_s"] = sum(row[k] for k in
                         ("scan_s", "read_after_s", "partition_s", "scatter_s"))
    row["alone_s"] -= row["ranks_cut_s"] + row["ranks_build_s"]
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="+")
    ap.add_argument("--out", required=True)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--partitioner", default="auto")
    ap.add_argument("--binary", default="target/release/contact-par")
    ap.add_argument("--split-parts", default="", help="comma-separated part counts")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for case in a.cases:
        runs = {"core": [], "none": []}
        with tempfile.TemporaryDirectory() as tmp:
            # One untimed run first, so that no timed run reads the file from disk.
            one_run(a.binary, case, a.ranks, "none", tmp, a.partitioner)
            for _ in range(a.runs):
                for bind in ("core", "none"):
                    runs[bind].append(one_run(a.binary, case, a.ranks, bind, tmp, a.partitioner))
        for bind, rs in runs.items():
            med = {k: statistics.median(r[k] for r in rs) for k in rs[0]}
            med.update(
                case=os.path.basename(case), ranks=a.ranks, runs=len(rs),
                bind=bind,
                # The first rank's cores for its work alone (host::on_idle_cores): one
                # when bound, else its node's ranks' share of the cores.
                cores=1 if bind == "core" else max(min(a.ranks, os.cpu_count() or 1), 1),
                nodes=rs[0]["nodes"], triangles=rs[0]["triangles"],
                serial_share=statistics.median(r["alone_s"] / r["total_s"] for r in rs),
            )
            rows.append(med)
    path = os.path.join(a.out, "start.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in FIELDS})
    print("| case | nodes | cores of the first rank | scan | assembly | problem | partition "
          "| of it, the ranks' cut and build | assembly and problem after the cut | scatter | alone "
          "| shares (all ranks) | checks and conditions (all ranks) | total | serial share "
          "| peak rank 0 / others (MB) |")
    print("| --- " * 16 + "|")
    for r in rows:
        print(f"| {r['case']} | {r['nodes']} | {r['cores']} | {r['scan_s']:.3f} | "
              f"{r['assembly_s']:.3f} | {r['problem_s']:.3f} | {r['partition_s']:.3f} | "
              f"{r['ranks_cut_s'] + r['ranks_build_s']:.3f} | {r['read_after_s']:.3f} | "
              f"{r['scatter_s']:.3f} | {r['alone_s']:.3f} | {r['shares_s']:.3f} | "
              f"{r['checks_s']:.3f} | "
              f"{r['total_s']:.3f} | {100 * r['serial_share']:.1f}% | "
              f"{r['rank0_peak_bytes'] / 1e6:.0f} / {r['other_peak_bytes'] / 1e6:.0f} |")
    print(f"wrote {path}")
    if a.split_parts:
        split_study(a)


def split_study(a):
    """`contact-par split` on one core: seconds (median of --runs) and peak memory."""
    rows = []
    for case in a.cases:
        for parts in (int(p) for p in a.split_parts.split(",")):
            secs, peaks = [], []
            for _ in range(a.runs):
                with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryFile("w+") as log:
                    cmd = ["taskset", "-c", "0", a.binary, "split", case,
                           "--parts", str(parts), "--out", tmp]
                    start = time.perf_counter()
                    child = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, text=True)
                    # wait4: this child's own peak resident memory (KiB on Linux).
                    _, status, usage = os.wait4(child.pid, 0)
                    secs.append(time.perf_counter() - start)
                    child.returncode = os.waitstatus_to_exitcode(status)
                    log.seek(0)
                    out = log.read()
                    if child.returncode != 0:
                        sys.exit(f"start_study: {' '.join(cmd)} failed:\n{out}")
                    peaks.append(usage.ru_maxrss * 1024)
                    nodes = int(re.search(r"split: (\d+) nodes", out).group(1))
            rows.append(dict(case=os.path.basename(case), nodes=nodes, parts=parts,
                             seconds=statistics.median(secs), peak_bytes=max(peaks)))
    path = os.path.join(a.out, "split.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["case", "nodes", "parts", "seconds", "peak_bytes"])
        w.writeheader()
        w.writerows(rows)
    print()
    print("| case | nodes | parts | `contact-par split`, one core (s) | peak (MB) | bytes per node |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['case']} | {r['nodes']} | {r['parts']} | {r['seconds']:.2f} | "
              f"{r['peak_bytes'] / 1e6:.0f} | {r['peak_bytes'] / r['nodes']:.0f} |")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
