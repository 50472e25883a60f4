#!/usr/bin/env python3
"""CSV files, plots and a markdown report from the runs of run-scripts/scaling.sh.

    python3 run-scripts/scaling_report.py DIR [--no-plots]

Reads DIR/runs.tsv (the index written by scaling.sh), DIR/meta.json and each run's
summary.json; writes DIR/runs.csv (one row per run), DIR/summary.csv (medians per
point), DIR/report.md, and with matplotlib DIR/speedup.png and DIR/phases.png.
Only the standard library is needed for everything but the plots.
"""

import csv
import json
import os
import statistics
import sys

# The phases of summary.json's "timings_s", in the order the program runs them. Any
# other key found there (a phase added later) is kept, before "total".
PHASES = ["read", "partition", "scatter", "assemble", "factor", "condense", "loop", "recover", "output"]
KEY = ("study", "case", "level", "ranks", "threads")


def num(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def load_runs(out):
    index = os.path.join(out, "runs.tsv")
    with open(index, newline="") as f:
        rows = list(csv.DictReader(f, delimiter="\t"))
    runs = []
    phases_seen = []
    for r in rows:
        run = {
            "study": r["study"],
            "case": r["case"],
            "level": int(r["level"]),
            "ranks": int(r["ranks"]),
            "threads": int(r["threads"]),
            "run": int(r["run"]),
            "exit_code": int(r["exit_code"]),
            "wall_s": float(r["wall_s"]),
            "cpu_s": num(r.get("cpu_s")),
            "user_s": num(r.get("user_s")),
            "sys_s": num(r.get("sys_s")),
            "minor_faults": num(r.get("minor_faults")),
            "others_cores": num(r.get("others_cores")),
            "time_maxrss_bytes": None if num(r.get("time_maxrss_kb")) is None
            else 1024 * num(r.get("time_maxrss_kb")),
            "dir": r["dir"],
        }
        path = os.path.join(out, r["dir"], "summary.json")
        s = None
        if os.path.exists(path):
            with open(path) as f:
                s = json.load(f)
        run["ok"] = s is not None and run["exit_code"] in (0, 3)
        if s is not None:
            # One entry per subdomain (several per rank with --subdomains-per-rank);
            # "per_rank" in the summaries of earlier versions.
            per = s.get("per_subdomain", s.get("per_rank", []))
            mem = s.get("peak_memory_bytes_per_rank") or [p.get("peak_memory_bytes", 0) for p in per]
            run.update(
                nodes=s.get("nodes"),
                dofs=s.get("dofs"),
                boundary_dofs=s.get("boundary_dofs"),
                contact_nodes=s.get("contact_nodes"),
                converged=s.get("converged"),
                iterations=s.get("iterations"),
                reported_threads=s.get("threads"),
                subdomains=s.get("subdomains", s.get("ranks")),
                peak_mem_max_bytes=max(mem) if mem else None,
                peak_mem_sum_bytes=sum(mem) if mem else None,
                factor_nnz_max=max((p.get("factor_nnz", 0) for p in per), default=None),
                factor_nnz_sum=sum(p.get("factor_nnz", 0) for p in per) if per else None,
                factor_gflop_max=max((p.get("factor_gflop", 0.0) for p in per), default=None),
                factor_gflop_sum=sum(p.get("factor_gflop", 0.0) for p in per) if per else None,
                interface_nodes_max=max((p.get("interface_nodes", 0) for p in per), default=None),
                assemble_max_s=max((p.get("assemble_s", 0.0) for p in per), default=None),
                factor_max_s=max((p.get("factor_s", 0.0) for p in per), default=None),
                loop_max_s=max((p.get("loop_s", 0.0) for p in per), default=None),
            )
            for k, v in s.get("timings_s", {}).items():
                run["t_" + k] = v
                if k != "total" and k not in phases_seen:
                    phases_seen.append(k)
            if run.get("iterations"):
                run["ms_per_sweep"] = 1e3 * run.get("t_loop", 0.0) / run["iterations"]
        runs.append(run)
    phases = [p for p in PHASES if p in phases_seen] + [p for p in phases_seen if p not in PHASES]
    return runs, phases


def fmt(v, digits=3):
    if v is None or v == "":
        return ""
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def write_csv(path, rows, columns):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({c: r.get(c, "") for c in columns})


def median(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def summarise(runs, phases, cores):
    points = {}
    for r in runs:
        points.setdefault(tuple(r[k] for k in KEY), []).append(r)
    timed = (["wall_s"] + ["t_" + p for p in phases]
             + ["t_total", "ms_per_sweep", "cpu_s", "user_s", "sys_s", "minor_faults",
                "others_cores", "time_maxrss_bytes"])
    rows = []
    for key, rs in points.items():
        ok = [r for r in rs if r["ok"]]
        row = dict(zip(KEY, key))
        row["ranks_x_threads"] = row["ranks"] * row["threads"]
        row["runs"] = len(rs)
        row["runs_ok"] = len(ok)
        row["all_converged"] = all(r.get("converged") for r in ok) if ok else False
        for c in ("nodes", "dofs", "boundary_dofs", "contact_nodes", "subdomains"):
            row[c] = ok[0].get(c) if ok else None
        iters = sorted({r.get("iterations") for r in ok})
        row["iterations"] = iters[0] if len(iters) == 1 else "/".join(map(str, iters))
        for c in timed + ["peak_mem_max_bytes", "peak_mem_sum_bytes", "factor_nnz_max",
                          "factor_nnz_sum", "factor_gflop_max", "factor_gflop_sum",
                          "interface_nodes_max", "assemble_max_s", "factor_max_s", "loop_max_s"]:
            row[c] = median([r.get(c) for r in ok])
        # The work of the factorization, counted from its structure: the same on every
        # run of a point, whatever the machine's load.
        if row.get("factor_gflop_max") and row.get("factor_gflop_sum"):
            parts = row.get("subdomains") or row["ranks"]
            row["work_imbalance"] = row["factor_gflop_max"] / (row["factor_gflop_sum"] / parts)
        totals = [r["t_total"] for r in ok if r.get("t_total") is not None]
        row["t_total_min"] = min(totals) if totals else None
        row["t_total_max"] = max(totals) if totals else None
        rows.append(row)

    # Speed-up and efficiency against the 1 rank x 1 thread point of the same study
    # (strong: same level; weak: the smallest level).
    for row in rows:
        if row["study"] in ("strong", "copies"):
            ref = next((q for q in rows if q["study"] == "strong" and q["level"] == row["level"]
                        and q["ranks"] == 1 and q["threads"] == 1), None)
        else:
            ref = next((q for q in rows if q["study"] == "weak" and q["ranks"] == 1
                        and q["threads"] == 1), None)
        n = row["ranks_x_threads"]
        usable = min(n, cores)
        if ref is None or not ref.get("t_total") or not row.get("t_total"):
            continue
        if row["study"] == "copies":
            # n copies did n times the work of the 1x1 point in the time of one copy.
            row["ceiling"] = n * ref["t_total"] / row["t_total"]
            row["ceiling_best"] = n * ref["t_total_min"] / row["t_total_min"]
        elif row["study"] == "strong":
            s = ref["t_total"] / row["t_total"]
            row["speedup"] = s
            row["speedup_best"] = ref["t_total_min"] / row["t_total_min"]
            row["efficiency"] = s / n
            row["efficiency_vs_cores"] = s / usable
            for p in phases:
                a, b = ref.get("t_" + p), row.get("t_" + p)
                if a and b:
                    row["speedup_" + p] = a / b
        else:
            # P ranks do P times the work: ideal time = T1 on P cores, T1 * P / c on c < P.
            e = ref["t_total"] / row["t_total"]
            row["efficiency"] = e
            row["efficiency_best"] = ref["t_total_min"] / row["t_total_min"]
            row["efficiency_vs_cores"] = e * n / usable
            row["work_ratio"] = (row["nodes"] or 0) / (ref["nodes"] or 1)
    for row in rows:
        if row["study"] != "strong" or not row.get("speedup"):
            continue
        c = next((q for q in rows if q["study"] == "copies" and q["level"] == row["level"]
                  and q["ranks"] == row["ranks_x_threads"] and q.get("ceiling")), None)
        if c is not None:
            row["ceiling"] = c["ceiling"]
            row["of_ceiling"] = row["speedup"] / c["ceiling"]
    order = {"strong": 0, "copies": 1, "weak": 2}
    rows.sort(key=lambda q: (order.get(q["study"], 2), q["level"] if q["study"] == "strong" else 0,
                             q["ranks"], q["threads"]))
    return rows


def load_average():
    try:
        with open("/proc/loadavg") as f:
            return " ".join(f.read().split()[:3])
    except OSError:
        return "unknown"


def mb(b):
    return None if b is None else b / 2**20


def table(header, lines):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join(" --- " for _ in header) + "|"]
    out += ["| " + " | ".join(fmt(v) for v in line) + " |" for line in lines]
    return "\n".join(out)


def report(out, meta, runs, rows, phases, plots):
    cores = meta.get("cores")
    L = []
    L.append("# contact-par scaling study\n")
    L.append(f"Generated from `runs.csv` by `run-scripts/scaling_report.py`.\n")
    L.append(f"* command: `{meta.get('command')}`")
    L.append(f"* date (UTC): {meta.get('date')}, host {meta.get('hostname')}")
    L.append(f"* machine: **{cores} core(s)** ({meta.get('cpu') or 'unknown CPU'}), "
             f"{(meta.get('memory_bytes') or 0) / 2**30:.1f} GiB memory; "
             f"load average at start {meta.get('load_average_at_start')}, when this report was "
             f"written {load_average()} (other users' work on the machine shows here)")
    extra = f" {meta['mpirun_args']}" if meta.get("mpirun_args") else ""
    L.append(f"* MPI: {meta.get('mpirun')}, `mpirun --oversubscribe --bind-to {meta.get('bind_to')}{extra}`")
    L.append(f"* binary: {meta.get('binary')} (sha256 {meta.get('binary_sha256_16')}..., copied to "
             f"bin/ before the runs); the scripts' checkout is at git {meta.get('git_commit')}"
             + (f" with {meta.get('git_dirty_files')} uncommitted file(s) in src/, partition/, "
                "Cargo.toml" if meta.get("git_dirty_files") else ""))
    case = (f"case file `{meta['case_file']}`" if meta.get("case_file")
            else f"built-in `{meta.get('case')}`")
    L.append(f"* case: {case}; every point is the median of "
             f"{meta.get('runs')} run(s), repetitions interleaved across points"
             + (f"; each run started once other processes used less than "
                f"{meta['wait_idle_cores']} core(s)" if meta.get("wait_idle_cores") else ""))
    failed = [r for r in runs if not r["ok"]]
    notconv = [r for r in runs if r["ok"] and not r.get("converged")]
    L.append(f"* runs: {len(runs)}, failed: {len(failed)}, not converged: {len(notconv)}")
    L.append("")
    busy = [r for r in rows if (r.get("others_cores") or 0) > 0.25]
    if busy:
        L.append("**Other work on the machine**: during the points "
                 + ", ".join(f"{r['study']} {r['ranks']}x{r['threads']} (L{r['level']})" for r in busy)
                 + " other processes kept more than a quarter of a core busy on average (column "
                 "`others' cores`: the machine's busy CPU time from /proc/stat minus this run's "
                 "own, per second of wall time). Those medians are slower than the solver is; "
                 "the best-run columns are the better estimate there.\n")
    L.append("Phase times are those of `summary.json` (`timings_s`, wall-clock seconds measured "
             "on rank 0; `total` excludes the MPI start-up, `wall` is the whole `mpirun` command). "
             "The loop synchronises every sweep, so its time is the same on every rank; the "
             "per-rank maxima of assemble and factor are in `summary.csv` (`assemble_max_s`, "
             "`factor_max_s`). Peak memory is the largest VmHWM over the ranks.")
    L.append("")
    if cores is not None:
        over = sorted({r["ranks_x_threads"] for r in rows if r["ranks_x_threads"] > cores})
        if over:
            L.append(f"**This machine has {cores} core(s)**: the points with ranks x threads = "
                     f"{', '.join(map(str, over))} are oversubscribed. Their speed-up cannot exceed "
                     f"{cores}; `eff/cores` divides by min(ranks x threads, cores) to show how "
                     "much of the machine was used, `eff` by ranks x threads as on a machine with "
                     "enough cores. What these points measure honestly is the overhead that "
                     "more subdomains add (interface size, condensation, communication), not "
                     "parallel speed-up.")
            L.append("")

    def cols_phase(r):
        return [r.get("t_" + p) for p in phases]

    for study in ("strong", "weak"):
        rs = [r for r in rows if r["study"] == study]
        if not rs:
            continue
        if study == "strong":
            L.append(f"## Strong scaling (fixed mesh, {mesh_label(meta.get('case_file'), rs[0])}, {rs[0]['nodes']} nodes, "
                     f"{rs[0]['dofs']} dofs)\n")
        else:
            L.append("## Weak scaling (each rank keeps about the same number of nodes)\n")
        L.append("Medians, seconds:\n")
        header = (["level", "nodes", "ranks", "threads", "subdomains", "ok runs", "sweeps"] + phases
                  + ["total", "total min-max", "wall", "ms/sweep", "peak MB/rank", "others' cores"])
        lines = []
        for r in rs:
            spread = (f"{r['t_total_min']:.3f}-{r['t_total_max']:.3f}"
                      if r.get("t_total_min") is not None else "")
            lines.append([r["level"], r["nodes"], r["ranks"], r["threads"], r.get("subdomains"),
                          f"{r['runs_ok']}/{r['runs']}", r["iterations"]] + cols_phase(r)
                         + [r.get("t_total"), spread, r.get("wall_s"), r.get("ms_per_sweep"),
                            mb(r.get("peak_mem_max_bytes")), r.get("others_cores")])
        L.append(table(header, lines))
        L.append("")
        if study == "strong":
            L.append("Speed-up of the median total time against 1 rank x 1 thread, efficiency, "
                     "the speed-up of the best run of each point (the run least disturbed by "
                     "other work on the machine), then the speed-up of each phase (medians):\n")
            sp_phases = [p for p in phases if p not in ("read", "output")]
            header = (["ranks", "threads", "ranks x threads", "speed-up", "eff", "eff/cores",
                       "speed-up (best run)", "ceiling", "speed-up / ceiling"]
                      + [f"S({p})" for p in sp_phases])
            lines = [[r["ranks"], r["threads"], r["ranks_x_threads"], r.get("speedup"),
                      r.get("efficiency"), r.get("efficiency_vs_cores"), r.get("speedup_best"),
                      r.get("ceiling"), r.get("of_ceiling")]
                     + [r.get("speedup_" + p) for p in sp_phases] for r in rs]
            L.append(table(header, lines))
            cs = [r for r in rows if r["study"] == "copies" and r["level"] == rs[0]["level"]]
            if cs:
                L.append("\n### The machine's ceiling\n")
                L.append("P independent copies of the 1 rank x 1 thread run, started together "
                         "(`copies` rows of `runs.csv`): P copies do P times the work of one in "
                         "the time a copy takes, so `ceiling` = P x T(1x1) / T(copy) is the "
                         "speed-up a P-way run reaches on this machine if it does the same work "
                         "as the 1-rank run and loses nothing to communication or imbalance. "
                         "It is below P where the cores share memory bandwidth and caches, or "
                         "(on a virtual machine) a host core; `speed-up / ceiling` above is the "
                         "part of the reachable speed-up the solver gets. A ceiling above P only "
                         "says that the machine was quieter during the copies than during the "
                         "1x1 runs. Medians over every copy of every repetition:\n")
                header = ["copies", "T(1x1) s", "T(copy) s", "copy min-max s", "ceiling",
                          "ceiling (best runs)", "others' cores"]
                lines = [[r["ranks"], next((q.get("t_total") for q in rs if q["ranks"] == 1
                                            and q["threads"] == 1), None),
                          r.get("t_total"),
                          (f"{r['t_total_min']:.3f}-{r['t_total_max']:.3f}"
                           if r.get("t_total_min") is not None else ""),
                          r.get("ceiling"), r.get("ceiling_best"), r.get("others_cores")]
                         for r in cs]
                L.append(table(header, lines))
            cpu_rows = [r for r in rs if r.get("user_s") is not None and r.get("sys_s") is not None]
            one = next((r for r in cpu_rows if r["ranks"] == 1 and r["threads"] == 1), None)
            if cpu_rows and one and one["user_s"] > 0 and one["sys_s"] > 0:
                L.append("\n### CPU time: user and system\n")
                L.append("CPU seconds of the whole run, all ranks together (`/usr/bin/time`: "
                         "user, system, minor page faults; medians). User time over the 1x1 "
                         "run's is the extra computation that more subdomains bring; system "
                         "time is mostly the kernel supplying memory written for the first "
                         "time, one page fault a page. On a virtual machine that hands freed "
                         "memory back to its host, that can be a third of a run and grow with "
                         "the ranks faulting at once: a speed-up is then bounded by "
                         "ranks x threads / `cpu ratio` as well as by the ceiling.\n")
                header = ["ranks", "threads", "user s", "system s", "system share",
                          "user ratio", "system ratio", "cpu ratio", "page faults (M)"]
                lines = []
                for r in cpu_rows:
                    cpu = r["user_s"] + r["sys_s"]
                    lines.append([r["ranks"], r["threads"], r["user_s"], r["sys_s"],
                                  r["sys_s"] / cpu if cpu > 0 else None,
                                  r["user_s"] / one["user_s"], r["sys_s"] / one["sys_s"],
                                  cpu / (one["user_s"] + one["sys_s"]),
                                  None if r.get("minor_faults") is None
                                  else r["minor_faults"] / 1e6])
                L.append(table(header, lines))
            ws = [r for r in rs if r.get("factor_gflop_max")]
            ref = next((r for r in ws if r["ranks"] == 1 and r["threads"] == 1), None)
            if ws and ref:
                L.append("\n### The factorization's work\n")
                L.append("Floating-point operations of the numeric factorizations, counted from "
                         "their structure (`factor_gflop` in summary.json: the same on every run, "
                         "free of the machine's load), per subdomain (one per rank, or one per "
                         "thread of a rank: see `subdomains`). The subdomains' total may exceed "
                         "one subdomain's (each one's boundary rows ride along to the end of its "
                         "factor) or fall below it (smaller pieces fill less); `imbalance` is the "
                         "largest subdomain's work over the mean; `work speed-up` = Gflop(1x1) / "
                         "the largest subdomain's Gflop is what the work alone predicts for the factor phase, "
                         "whose measured speed-up S(factor) also holds the ordering (not "
                         "counted here), memory bandwidth, and the kernels' speed on fronts of "
                         "each size:\n")
                header = ["ranks", "threads", "subdomains", "Gflop (all)", "Gflop (largest)",
                          "imbalance", "work speed-up", "S(factor)"]
                lines = [[r["ranks"], r["threads"], r.get("subdomains"), r["factor_gflop_sum"],
                          r["factor_gflop_max"],
                          r.get("work_imbalance"), ref["factor_gflop_max"] / r["factor_gflop_max"],
                          r.get("speedup_factor")]
                         for r in ws]
                L.append(table(header, lines))
        else:
            L.append("Weak-scaling efficiency T(1 rank) / T(P ranks) of the total time; "
                     "`eff/cores` is relative to the best time possible on this machine's "
                     "cores (T1 x ranks / min(ranks, cores)):\n")
            header = ["level", "nodes", "nodes ratio", "ranks", "eff", "eff/cores",
                      "eff (best runs)", "sweeps", "boundary dofs"]
            lines = [[r["level"], r["nodes"], r.get("work_ratio"), r["ranks"], r.get("efficiency"),
                      r.get("efficiency_vs_cores"), r.get("efficiency_best"), r["iterations"],
                      r.get("boundary_dofs")]
                     for r in rs]
            L.append(table(header, lines))
            sweeps = [r["iterations"] for r in rs if isinstance(r["iterations"], int)]
            if sweeps and max(sweeps) > 1.1 * min(sweeps):
                L.append(f"\nThe sweep count grows with the mesh ({min(sweeps)} to {max(sweeps)}), "
                         "so part of the weak-scaling loss is algorithmic, not parallel: compare "
                         "ms/sweep above.")
        L.append("")
        # Where the time goes: the largest phase of each point.
        notes = []
        for r in rs:
            ph = [(r.get("t_" + p) or 0.0, p) for p in phases]
            if not ph or not r.get("t_total"):
                continue
            v, p = max(ph)
            notes.append(f"{r['ranks']}x{r['threads']} (level {r['level']}): {p} "
                         f"{100 * v / r['t_total']:.0f}%")
        if notes:
            L.append("Largest phase per point: " + "; ".join(notes) + ".\n")
    if plots:
        L.append("## Plots\n")
        for name, what in (("speedup.png", "speed-up and efficiency"),
                           ("phases.png", "phase breakdown (median seconds)")):
            if os.path.exists(os.path.join(out, name)):
                L.append(f"![{what}]({name})\n")
    if failed:
        L.append("## Failed runs\n")
        for r in failed:
            L.append(f"* {r['study']} level {r['level']} {r['ranks']}x{r['threads']} run {r['run']}: "
                     f"exit code {r['exit_code']}, see `{r['dir']}/stderr.txt`")
        L.append("")
    L.append("## Files\n")
    L.append("`runs.csv` one row per run; `summary.csv` medians per point with speed-up and "
             "efficiency; `meta.json` the machine and the command; `runs/` each run's "
             "summary.json, history.csv, stdout and stderr.")
    with open(os.path.join(out, "report.md"), "w") as f:
        f.write("\n".join(L) + "\n")


def mesh_label(case_file, row):
    """What a strong study's fixed mesh is called: its case file, or the built-in level."""
    return f"case file {case_file}" if case_file else f"level {row['level']}"


def plot(out, rows, phases, cores, case_file=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not any(r.get("t_total") for r in rows):
        return False
    strong = [r for r in rows if r["study"] == "strong" and r.get("speedup")]
    weak = [r for r in rows if r["study"] == "weak" and r.get("efficiency")]
    ncols = 2 + (1 if weak else 0)
    fig, axes = plt.subplots(1, ncols, figsize=(5 * ncols, 4))
    ax_s, ax_e = axes[0], axes[1]
    xs_all = sorted({r["ranks_x_threads"] for r in strong}) or [1]
    xmax = max(xs_all)
    ideal = list(range(1, xmax + 1))
    ax_s.plot(ideal, ideal, "k--", lw=0.8, label="ideal")
    ax_s.plot(ideal, [min(x, cores) for x in ideal], "k:", lw=0.8, label=f"{cores} cores")
    for t in sorted({r["threads"] for r in strong}):
        pts = sorted((r["ranks_x_threads"], r["speedup"], r["efficiency"], r["efficiency_vs_cores"],
                      r.get("speedup_best") or 0.0)
                     for r in strong if r["threads"] == t)
        x = [p[0] for p in pts]
        line = ax_s.plot(x, [p[1] for p in pts], "o-", label=f"{t} thread(s)/rank, median")[0]
        ax_s.plot(x, [p[4] for p in pts], "^--", color=line.get_color(), alpha=0.6,
                  label=f"{t} thread(s)/rank, best run")
        ax_e.plot(x, [p[2] for p in pts], "o-", label=f"eff, {t} thread(s)/rank")
        ax_e.plot(x, [p[3] for p in pts], "s--", alpha=0.6, label=f"eff/cores, {t} thread(s)/rank")
    ceil = sorted((r["ranks"], r["ceiling"]) for r in rows
                  if r["study"] == "copies" and r.get("ceiling"))
    if ceil:
        ax_s.plot([c[0] for c in ceil], [c[1] for c in ceil], "k*", ms=10,
                  label="ceiling: copies of 1x1 at once")
    if strong:
        ax_s.set_title(f"strong scaling, {mesh_label(case_file, strong[0])} "
                       f"({strong[0]['nodes']} nodes)")
    ax_s.set_xlabel("ranks x threads")
    ax_s.set_ylabel("speed-up (median total time)")
    ax_s.legend(fontsize=8)
    ax_s.grid(alpha=0.3)
    ax_e.axhline(1.0, color="k", lw=0.8, ls="--")
    ax_e.set_xlabel("ranks x threads")
    ax_e.set_ylabel("efficiency")
    ax_e.set_ylim(bottom=0)
    ax_e.set_title("strong-scaling efficiency")
    ax_e.legend(fontsize=7)
    ax_e.grid(alpha=0.3)
    if weak:
        ax_w = axes[2]
        pts = sorted((r["ranks"], r["efficiency"], r["efficiency_vs_cores"], r["level"],
                      r.get("efficiency_best") or 0.0) for r in weak)
        ax_w.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label="T1 / TP (medians)")
        ax_w.plot([p[0] for p in pts], [p[4] for p in pts], "^--", alpha=0.6, label="best runs")
        ax_w.plot([p[0] for p in pts], [p[2] for p in pts], "s--", label="medians, vs cores")
        for p in pts:
            ax_w.annotate(f"L{p[3]}", (p[0], p[1]), textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax_w.axhline(1.0, color="k", lw=0.8, ls="--")
        ax_w.set_xscale("log", base=2)
        ax_w.set_xlabel("ranks (1 thread each)")
        ax_w.set_ylabel("weak-scaling efficiency")
        ax_w.set_ylim(bottom=0)
        ax_w.set_title("weak scaling")
        ax_w.legend(fontsize=8)
        ax_w.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "speedup.png"), dpi=120)
    plt.close(fig)

    studies = [s for s in ("strong", "weak") if any(r["study"] == s for r in rows)]
    fig, axes = plt.subplots(1, len(studies), figsize=(7 * len(studies), 4.2), squeeze=False)
    for ax, study in zip(axes[0], studies):
        rs = [r for r in rows if r["study"] == study and r.get("t_total")]
        labels = [f"{r['ranks']}x{r['threads']}" + (f"\nL{r['level']}" if study == "weak" else "")
                  for r in rs]
        bottom = [0.0] * len(rs)
        for p in phases + ["other"]:
            if p == "other":
                # Time in no phase (distribution of the sub-meshes, waits), and the
                # difference between the median total and the sum of the phase medians.
                vals = [max(0.0, r["t_total"] - sum(r.get("t_" + q) or 0.0 for q in phases)) for r in rs]
            else:
                vals = [r.get("t_" + p) or 0.0 for r in rs]
            if not any(v > 0 for v in vals):
                continue
            ax.bar(labels, vals, bottom=bottom, label=p)
            bottom = [b + v for b, v in zip(bottom, vals)]
        ax.set_ylabel("median seconds")
        ax.set_xlabel("ranks x threads")
        ax.set_title(f"{study} scaling: phase breakdown")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "phases.png"), dpi=120)
    plt.close(fig)
    return True


def main(argv):
    args = [a for a in argv if not a.startswith("--")]
    if len(args) != 1:
        sys.exit(__doc__)
    out = args[0]
    want_plots = "--no-plots" not in argv
    meta = {}
    if os.path.exists(os.path.join(out, "meta.json")):
        with open(os.path.join(out, "meta.json")) as f:
            meta = json.load(f)
    cores = meta.get("cores") or os.cpu_count() or 1
    runs, phases = load_runs(out)
    run_cols = (["study", "case", "level", "nodes", "dofs", "ranks", "threads", "subdomains", "run",
                 "exit_code",
                 "converged", "iterations", "wall_s"]
                + ["t_" + p for p in phases]
                + ["t_total", "ms_per_sweep", "cpu_s", "user_s", "sys_s", "minor_faults",
                   "others_cores", "peak_mem_max_bytes", "peak_mem_sum_bytes", "time_maxrss_bytes",
                   "factor_nnz_max", "factor_nnz_sum", "factor_gflop_max", "factor_gflop_sum",
                   "boundary_dofs", "interface_nodes_max",
                   "assemble_max_s", "factor_max_s", "loop_max_s", "reported_threads", "dir"])
    write_csv(os.path.join(out, "runs.csv"), runs, run_cols)
    rows = summarise(runs, phases, cores)
    sum_cols = (["study", "case", "level", "nodes", "dofs", "ranks", "threads", "subdomains",
                 "ranks_x_threads",
                 "runs", "runs_ok", "all_converged", "iterations", "wall_s"]
                + ["t_" + p for p in phases]
                + ["t_total", "t_total_min", "t_total_max", "ms_per_sweep", "cpu_s", "user_s",
                   "sys_s", "minor_faults", "others_cores",
                   "speedup", "speedup_best", "efficiency", "efficiency_best",
                   "efficiency_vs_cores", "work_ratio", "ceiling", "ceiling_best", "of_ceiling"]
                + ["speedup_" + p for p in phases]
                + ["peak_mem_max_bytes", "peak_mem_sum_bytes", "time_maxrss_bytes",
                   "factor_nnz_max", "factor_nnz_sum", "factor_gflop_max", "factor_gflop_sum",
                   "work_imbalance",
                   "boundary_dofs", "interface_nodes_max", "assemble_max_s", "factor_max_s",
                   "loop_max_s"])
    write_csv(os.path.join(out, "summary.csv"), rows, sum_cols)
    plotted = False
    if want_plots:
        try:
            plotted = plot(out, rows, phases, cores, meta.get("case_file"))
        except ImportError:
            print("scaling_report.py: matplotlib is not available; no plots", file=sys.stderr)
    report(out, meta, runs, rows, phases, plotted)
    bad = [r for r in runs if not r["ok"]]
    for r in bad:
        print(f"scaling_report.py: run {r['dir']} failed (exit code {r['exit_code']})", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
