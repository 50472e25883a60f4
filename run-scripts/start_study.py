#!/usr/bin/env python3
"""The start of a run from one mesh file, phase by phase: what the first rank does alone
while the others wait (the mesh read, the problem, the partition and split, the
scatter), on one core and on all of its node's cores.

    python3 run-scripts/start_study.py CASE.toml [CASE.toml ...] --out DIR \\
        [--ranks 2] [--runs 3] [--partitioner auto|geometric|metis]
        [--binary target/release/contact-par] [--split-parts 2,64,512]

Each case runs on --ranks ranks, alternately `--bind-to core --borrow-idle-cores false`
(the first rank has one core for its work alone) and `--bind-to none` (it borrows the
cores of the ranks of its node), --runs times each; the medians go to DIR/start.csv and
a table on stdout. The pieces are read from the phase lines: the read's mesh and
problem, the partition, the scatter. `serial share` is the first rank's seconds alone
(read, partition, scatter) over the whole run's.

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
    r"; mesh ([\d.]+) s, problem ([\d.]+) s"
)
PHASE = re.compile(r"^(\w+)\s+done in\s+([\d.]+) s")
TOTAL = re.compile(r"^total\s+([\d.]+)")

FIELDS = [
    "case", "nodes", "triangles", "ranks", "bind", "cores", "runs",
    "read_s", "mesh_s", "problem_s", "partition_s", "scatter_s",
    "alone_s", "total_s", "serial_share", "rank0_peak_bytes", "other_peak_bytes",
]


def one_run(binary, case, ranks, bind, out, partitioner):
    if bind == "core" and (os.cpu_count() or 1) < ranks:
        # Open MPI refuses to bind more ranks than cores: the one-core figures are then
        # the unbound ones, and the fitted threaded shares zero.
        bind = "none"
    cmd = [
        "mpirun", "-n", str(ranks), "--oversubscribe", "--bind-to", bind,
        binary, case, "--threads", "1", "--no-plots", "--out", out,
        "--partitioner", partitioner,
        # Ranks bound to their cores lend them too unless told not to.
        "--borrow-idle-cores", "false" if bind == "core" else "true",
    ]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"start_study: {' '.join(cmd)} failed:\n{p.stderr}")
    row = {}
    for line in p.stdout.splitlines():
        m = READ.match(line)
        if m:
            read, nodes, tris, mesh, problem = m.groups()
            row.update(read_s=float(read), nodes=int(nodes), triangles=int(tris),
                       mesh_s=float(mesh), problem_s=float(problem))
            continue
        m = PHASE.match(line)
        if m and m.group(1) in ("partition", "scatter"):
            row[m.group(1) + "_s"] = float(m.group(2))
        m = TOTAL.match(line)
        if m:
            row["total_s"] = float(m.group(1))
    if "mesh_s" not in row:
        sys.exit(f"start_study: {case}: the read line names no mesh file's seconds "
                 "(a case with a mesh file is needed)")
    with open(os.path.join(out, "summary.json")) as f:
        peaks = json.load(f)["peak_memory_bytes_per_rank"]
    row["rank0_peak_bytes"] = peaks[0]
    row["other_peak_bytes"] = statistics.median(peaks[1:]) if len(peaks) > 1 else 0
    row["alone_s"] = row["read_s"] + row["partition_s"] + row["scatter_s"]
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
    print("| case | nodes | cores of the first rank | mesh | problem | partition | scatter "
          "| alone | total | serial share | peak rank 0 / others (MB) |")
    print("| --- " * 11 + "|")
    for r in rows:
        print(f"| {r['case']} | {r['nodes']} | {r['cores']} | {r['mesh_s']:.3f} | "
              f"{r['problem_s']:.3f} | {r['partition_s']:.3f} | {r['scatter_s']:.3f} | "
              f"{r['alone_s']:.3f} | {r['total_s']:.3f} | {100 * r['serial_share']:.1f}% | "
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
