#!/usr/bin/env python3
"""The partition of a run from one mesh file by the first rank, its straight cuts
(`--partitioner geometric`, the default; METIS where a part would be in pieces) against
METIS (`--partitioner metis`), against the rank count: each piece's seconds and the
parts' quality.

    python3 run-scripts/cut_study.py CASE.toml [CASE.toml ...] --out DIR \\
        [--ranks 2,4,8,16,32] [--runs 3] [--partitioners geometric,metis] [--append]
        [--binary target/release/contact-par]

Each case runs on each rank count (`--oversubscribe --bind-to none`, one thread and one
subdomain per rank), with each partitioner in turn, --runs times; a run is stopped once
its partition line is out (the rest of the run is not this study's). The partition line
names its pieces: the dual graph, the cut (and the method that made it) and the split.
Medians go to DIR/cut.csv (with --append, after its rows) and a table on stdout, with
the edge cut and the interface nodes.
"""
import argparse
import csv
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile

READ = re.compile(r"^read\s+done in .*?: (\d+) nodes, (\d+) triangles")
PART = re.compile(
    r"^partition done in\s+([\d.]+) s: graph ([\d.]+) s, cut ([\d.]+) s \((.*?)\), "
    r"split ([\d.]+) s: .*?edge cut (\d+); (\d+) interface nodes"
)
FIELDS = [
    "case", "nodes", "triangles", "ranks", "partitioner", "method", "runs", "partition_s",
    "graph_s", "cut_s", "split_s", "edge_cut", "interface_nodes",
]


def one_run(binary, case, ranks, partitioner, out):
    cmd = [
        "mpirun", "-n", str(ranks), "--oversubscribe", "--bind-to", "none", binary, case,
        "--threads", "1", "--subdomains-per-rank", "1", "--no-plots", "--out", out,
        "--partitioner", partitioner,
    ]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         start_new_session=True)
    row, seen = None, []
    for line in p.stdout:
        seen.append(line)
        m = READ.match(line)
        if m:
            nodes, tris = int(m.group(1)), int(m.group(2))
        m = PART.match(line)
        if m:
            total, graph, cut, method, split, edges, itf = m.groups()
            row = dict(nodes=nodes, triangles=tris, partition_s=float(total),
                       graph_s=float(graph), cut_s=float(cut), split_s=float(split),
                       edge_cut=int(edges), interface_nodes=int(itf), method=method)
            break
    # The run past its partition is not measured: the whole job is stopped.
    try:
        os.killpg(p.pid, signal.SIGTERM)
        p.wait(timeout=10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    if row is None:
        sys.exit(f"cut_study: {' '.join(cmd)} printed no partition line:\n{''.join(seen)}")
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="+")
    ap.add_argument("--out", required=True)
    ap.add_argument("--ranks", default="2,4,8,16,32")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--partitioners", default="geometric,metis")
    ap.add_argument("--append", action="store_true", help="add the rows to DIR/cut.csv")
    ap.add_argument("--binary", default="target/release/contact-par")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for case in a.cases:
        for ranks in (int(r) for r in a.ranks.split(",")):
            runs = {name: [] for name in a.partitioners.split(",")}
            with tempfile.TemporaryDirectory() as tmp:
                one_run(a.binary, case, ranks, "metis", tmp)  # the file into the page cache
                for _ in range(a.runs):
                    for partitioner in runs:
                        runs[partitioner].append(one_run(a.binary, case, ranks, partitioner, tmp))
            for partitioner, rs in runs.items():
                med = {k: statistics.median(r[k] for r in rs) for k in rs[0] if k != "method"}
                # The method of each run (straight cuts fall back to METIS where a part
                # would be in pieces).
                methods = sorted({r["method"] for r in rs})
                med.update(case=os.path.basename(case), ranks=ranks, runs=len(rs),
                           partitioner=partitioner, method="/".join(methods),
                           nodes=rs[0]["nodes"], triangles=rs[0]["triangles"])
                rows.append(med)
    path = os.path.join(a.out, "cut.csv")
    append = a.append and os.path.exists(path)
    with open(path, "a" if append else "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        if not append:
            w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in FIELDS})
    print("| case | triangles | ranks | partitioner | method | graph | cut | split | partition "
          "| edge cut | interface nodes |")
    print("| --- " * 11 + "|")
    for r in rows:
        print(f"| {r['case']} | {r['triangles']} | {r['ranks']} | {r['partitioner']} | "
              f"{r['method']} | {r['graph_s']:.3f} | {r['cut_s']:.3f} | "
              f"{r['split_s']:.3f} | {r['partition_s']:.3f} | {r['edge_cut']:.0f} | "
              f"{r['interface_nodes']:.0f} |")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
