#!/usr/bin/env python3
"""How much of a run's wall time the machine's cores spend running it one at a time:
Amdahl's serial share, measured from outside, whatever rank or thread does the work.

    python3 run-scripts/one_core_time.py [--runs 3] [--bin-ms 10] [--top 12] \\
        [--program contact-par] -- \\
        mpirun -n 2 target/release/contact-par CASE.toml --quiet --no-plots

`perf record -a -e cpu-clock` samples every core at 1 kHz while the command runs; each
bin of --bin-ms milliseconds counts a core as running the program where more than half
of that core's samples in the bin are the program's (its processes and threads, by the
binary's file name, --program, and its `free` thread). The report: per run, the window
from the program's first sample to its last, and the seconds with 0, 1, 2, ... cores
running it; then, over the last run's one-core bins, the functions sampled most (where
the one-core time goes). Needs `perf` and the right to sample the whole machine (root,
or kernel.perf_event_paranoid <= 0). perf's sampling slows the run by a few per cent.

The start of a run on several ranks (the first rank's read and partition while the
others sleep) runs on the cores the others lend it (docs/performance.md, "Ranks bound to
their cores"): there the wall time of the first rank's start overstates the serial share,
and this count does not.
"""

import argparse
import collections
import os
import statistics
import subprocess
import sys
import tempfile


def samples(perf_data):
    """(time, cpu, command, symbol) of every sample."""
    out = subprocess.run(
        ["perf", "script", "-i", perf_data, "-F", "comm,tid,cpu,time,ip,sym"],
        capture_output=True, text=True, check=True).stdout
    rows = []
    for line in out.splitlines():
        parts = line.split()
        k = next((i for i, p in enumerate(parts) if p.startswith("[") and p.endswith("]")), None)
        if k is None or k < 2 or len(parts) < k + 2:
            continue
        try:
            t = float(parts[k + 1].rstrip(":"))
            cpu = int(parts[k][1:-1])
        except ValueError:
            continue
        comm = " ".join(parts[:k - 1])
        sym = " ".join(parts[k + 3:]) if len(parts) > k + 3 else "?"
        rows.append((t, cpu, comm, sym))
    return rows


def busy_bins(rows, names, bin_s):
    """Per bin: the cores that ran the program, and its symbols there."""
    mine = [r for r in rows if r[2].startswith(names)]
    if not mine:
        return None
    t0, t1 = mine[0][0], mine[-1][0]
    total = collections.defaultdict(collections.Counter)
    ours = collections.defaultdict(collections.Counter)
    syms = collections.defaultdict(collections.Counter)
    for t, cpu, comm, sym in rows:
        if t0 <= t <= t1:
            b = int((t - t0) / bin_s)
            total[b][cpu] += 1
            if comm.startswith(names):
                ours[b][cpu] += 1
                syms[b][sym[:70]] += 1
    nbins = int((t1 - t0) / bin_s) + 1
    cores = [sum(1 for c, n in total[b].items() if ours[b][c] * 2 > n) for b in range(nbins)]
    return cores, syms


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--bin-ms", type=float, default=10.0)
    ap.add_argument("--top", type=int, default=12)
    ap.add_argument("--program", default="contact-par",
                    help="the binary's file name, which names its processes (default contact-par)")
    ap.add_argument("command", nargs=argparse.REMAINDER)
    args = ap.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        sys.exit("one_core_time.py: give the command after --")
    binary = args.program
    names = (binary[:15], "free")
    bin_s = args.bin_ms / 1000.0
    shares = []
    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, "perf.data")
        for run in range(args.runs):
            subprocess.run(["perf", "record", "-q", "-a", "-e", "cpu-clock", "-F", "1000",
                            "-o", data, "--"] + command,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
            found = busy_bins(samples(data), names, bin_s)
            if found is None:
                sys.exit(f"one_core_time.py: no samples of {binary}")
            cores, syms = found
            hist = collections.Counter(cores)
            wall = len(cores) * bin_s
            serial = (hist[0] + hist[1]) * bin_s
            shares.append(serial / wall)
            print(f"run {run + 1}: window {wall:.2f} s; " +
                  ", ".join(f"{k} core(s) {hist[k] * bin_s:.2f} s" for k in sorted(hist)) +
                  f"; at most one core {serial:.2f} s ({100 * serial / wall:.1f}%)")
    print(f"median share at most one core: {100 * statistics.median(shares):.1f}%")
    top = collections.Counter()
    for b, n in enumerate(cores):
        if n == 1:
            top.update(syms[b])
    count = sum(top.values())
    one = collections.Counter(cores)[1] * bin_s
    print("the last run's one-core time by function (ms):")
    for sym, n in top.most_common(args.top):
        print(f"  {1000 * one * n / count:6.0f}  {sym}")


if __name__ == "__main__":
    main()
