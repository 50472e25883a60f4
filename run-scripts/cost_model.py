#!/usr/bin/env python3
"""The cost model of docs/cost-model.md: fitted to the summary.json files of a scaling
study (run-scripts/scale_study.sh --keep), then used to predict a run of any size.

    python3 run-scripts/cost_model.py STUDY_DIR/summary-*.json [--dofs 1e8 --ranks 512]
        [--contact-nodes N] [--sweeps S] [--flops 12e9 --bandwidth 10e9
        --latency 2e-6 --net-bandwidth 10e9 --mumps-efficiency 0.3]

Every fit is printed with its residuals (model over measurement) on the data it came
from, then the prediction. Only flops, sizes, bytes and memory are fitted (the same on
an oversubscribed machine as on a cluster); times follow from them and the node's
parameters, which are arguments.
"""
import argparse
import json
import math
import statistics
import sys


def load(paths):
    runs = []
    for p in paths:
        s = json.load(open(p))
        runs.append(s)
    runs.sort(key=lambda s: (s["dofs"], s["subdomains"]))
    return runs


def fit_ratio(pairs):
    """The a of y = a x by least squares on log y - log x (relative errors)."""
    return math.exp(statistics.mean(math.log(y) - math.log(x) for x, y in pairs if x > 0 and y > 0))


def fit_power(pairs):
    """y = a x^g by least squares in log-log."""
    xs = [math.log(x) for x, y in pairs]
    ys = [math.log(y) for x, y in pairs]
    mx, my = statistics.mean(xs), statistics.mean(ys)
    g = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return math.exp(my - g * mx), g


def fit_two(rows):
    """y = a x1 + b x2 minimising the sum of (model / y - 1)^2."""
    s11 = sum((x1 / y) ** 2 for (x1, _), y in rows)
    s22 = sum((x2 / y) ** 2 for (_, x2), y in rows)
    s12 = sum(x1 * x2 / y**2 for (x1, x2), y in rows)
    r1 = sum(x1 / y for (x1, _), y in rows)
    r2 = sum(x2 / y for (_, x2), y in rows)
    det = s11 * s22 - s12 * s12
    return (r1 * s22 - r2 * s12) / det, (s11 * r2 - s12 * r1) / det


def fit_linear(pairs):
    """y = a + b x by least squares."""
    xs, ys = [x for x, _ in pairs], [y for _, y in pairs]
    mx, my = statistics.mean(xs), statistics.mean(ys)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return my - b * mx, b


class Model:
    """Per subdomain s of a run of n dofs on P subdomains (one per rank):
    n_s = n / P, its interface dofs i_s = a_i sqrt(n_s), its contact dofs c_s = C / P
    (the partition balances the contact nodes), its dense block b_s = c_s + i_s;
    factor work F_s = a_f n_s^1.5 + a_d b_s^3 (sparse nested dissection of the interior,
    then the dense trailing block, whose Cholesky alone is b_s^3 / 3); the interface system n_G = a_G sqrt(n P), its work
    F_G = a_I n_G^g spread over the ranks by MUMPS (the largest share k_I F_G / P),
    its factor entries E_G = f_E sum_s b_s^2 / 2 (the subdomains' dense blocks assembled,
    f_E the fill, an assumption); memory per rank M = M_0 + m_n n_s + 8 b_s^2 +
    8 E_G / P (bytes)."""

    def __init__(self, runs):
        self.runs = runs
        subs = [(s, q) for s in runs for q in s["per_subdomain"]]
        dofs = lambda q: 2 * q["nodes"]
        contact_dofs = lambda s, q: q["boundary_dofs"] - q.get("interface_dofs_est", 0)
        # Interface dofs of a subdomain: its boundary dofs less its own contact dofs
        # (the contact dofs per node are 1 without friction, 2 with).
        self.contact_per_node = {}
        for s in runs:
            frictional = s["friction"] != "none"
            self.contact_per_node[id(s)] = 2 if frictional else 1
        multi = [(s, q) for s, q in subs if s["subdomains"] > 1]
        self.a_i = fit_ratio(
            [(math.sqrt(dofs(q)), self.interface_of(s, q)) for s, q in multi if self.interface_of(s, q) > 0]
        )
        # F_s = a_f n_s^1.5 + a_d b_s^3, least squares on relative errors.
        rows = [((dofs(q) ** 1.5, q["boundary_dofs"] ** 3), q["factor_gflop"] * 1e9) for _, q in subs]
        self.a_f, self.a_d = fit_two(rows)
        self.a_G = fit_ratio([(math.sqrt(s["dofs"] * s["subdomains"]), s["interface_dofs"]) for s in runs if s["subdomains"] > 1])
        mumps = [s for s in runs if s.get("interface_factor") == "mumps"]
        if len(mumps) >= 2:
            self.a_I, self.g = fit_power([(s["interface_dofs"], s["interface_gflop"] * 1e9) for s in mumps])
            self.k_I = max(
                max(q["interface_gflop"] for q in s["per_subdomain"]) / (s["interface_gflop"] / s["subdomains"])
                for s in mumps
            )
        else:
            self.a_I, self.g, self.k_I = float("nan"), float("nan"), float("nan")
        self.f_E = 2.0
        pts = []
        for s in runs:
            peaks = s["peak_memory_bytes_per_rank"]
            for q, m in zip(s["per_subdomain"], peaks):
                rest = m - 8 * q["boundary_dofs"] ** 2 - 8 * self.entries(s) / s["subdomains"]
                pts.append((dofs(q), rest))
        self.M_0, self.m_n = fit_linear(pts)

    def interface_of(self, s, q):
        return max(q["boundary_dofs"] - self.contact_per_node[id(s)] * q["contact_nodes"], 0)

    def entries(self, s):
        if s.get("interface_factor") != "mumps":
            return 0.0
        return self.f_E * sum(q["boundary_dofs"] ** 2 for q in s["per_subdomain"]) / 2

    def predict(self, n, P, contact_dofs):
        n_s = n / P
        i_s = self.a_i * math.sqrt(n_s) if P > 1 else 0.0
        b_s = contact_dofs / P + i_s
        F_s = self.a_f * n_s**1.5 + self.a_d * b_s**3
        n_G = self.a_G * math.sqrt(n * P) if P > 1 else 0.0
        F_G = self.a_I * n_G**self.g if P > 1 else 0.0
        share = self.k_I * F_G / P
        E_G = self.f_E * P * b_s**2 / 2
        M = self.M_0 + self.m_n * n_s + 8 * b_s**2 + 8 * E_G / P
        return dict(n_s=n_s, i_s=i_s, b_s=b_s, F_s=F_s, n_G=n_G, F_G=F_G, share=share, E_G=E_G, M=M)


def times(m, pred, P, sweeps, a):
    """Seconds: factor (critical path), one sweep, the loop, from the node's parameters."""
    factor = pred["F_s"] / a.flops + pred["share"] / (a.mumps_efficiency * a.flops)
    # A sweep reads each subdomain's dense blocks twice (forward and backward) and its
    # share of the interface factor twice; it makes one all-reduce, the interface
    # solve's tree (2 log2 P messages) and the all-to-all of its solution entries.
    local = 2 * 8 * pred["b_s"] ** 2 / a.bandwidth
    itf = 2 * 8 * pred["E_G"] / P / a.bandwidth if P > 1 else 0.0
    msgs = (1 + 2 * math.ceil(math.log2(P))) * a.latency if P > 1 else 0.0
    volume = 8 * (pred["i_s"] * 2 + 32) / a.net_bandwidth
    sweep = local + itf + msgs + volume
    return factor, sweep, sweeps * sweep


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("summaries", nargs="+")
    ap.add_argument("--dofs", type=float, default=1e8)
    ap.add_argument("--ranks", type=int, default=512)
    ap.add_argument("--contact-nodes", type=float, default=None,
                    help="default: the study's, scaled like the boundary (sqrt of the dofs)")
    ap.add_argument("--sweeps", type=float, default=None, help="default: the study's largest run's")
    ap.add_argument("--flops", type=float, default=None,
                    help="flop/s of one core in the factorization (default: the one-rank run's)")
    ap.add_argument("--bandwidth", type=float, default=10e9, help="memory bytes/s per core")
    ap.add_argument("--latency", type=float, default=2e-6, help="network latency, s")
    ap.add_argument("--net-bandwidth", type=float, default=10e9, help="network bytes/s per rank")
    ap.add_argument("--mumps-efficiency", type=float, default=0.3,
                    help="MUMPS's flop rate over --flops in the interface factorization")
    a = ap.parse_args()
    runs = load(a.summaries)
    m = Model(runs)
    if a.flops is None:
        one = [s for s in runs if s["subdomains"] == 1]
        s = one[-1] if one else runs[0]
        q = max(s["per_subdomain"], key=lambda q: q["factor_gflop"])
        a.flops = q["factor_gflop"] * 1e9 / q["factor_s"]
    print(f"fit: interface dofs of a subdomain i_s = {m.a_i:.3f} sqrt(n_s); factor F_s = {m.a_f:.1f} n_s^1.5 + {m.a_d:.3f} b_s^3;")
    print(f"     interface n_G = {m.a_G:.3f} sqrt(n P); MUMPS work F_G = {m.a_I:.3g} n_G^{m.g:.2f}, largest share {m.k_I:.2f} F_G / P;")
    print(f"     memory M = {m.M_0 / 1e6:.0f} MB + {m.m_n:.0f} B x n_s + 8 b_s^2 + 8 E_G / P  (E_G = {m.f_E} sum b_s^2 / 2, assumed)")
    print(f"     node: {a.flops / 1e9:.1f} Gflop/s, {a.bandwidth / 1e9:.0f} GB/s, latency {a.latency * 1e6:.1f} us, network {a.net_bandwidth / 1e9:.0f} GB/s, MUMPS at {a.mumps_efficiency:.0%}")
    print()
    print("check on the study (model / measured):")
    print(f"{'dofs':>9} {'P':>4} {'n_G':>12} {'critical Gflop':>16} {'median MB':>14} {'max MB':>14}")
    for s in runs:
        P = s["subdomains"]
        c = m.contact_per_node[id(s)] * s["contact_nodes"]
        pr = m.predict(s["dofs"], P, c)
        per = s["per_subdomain"]
        crit = max(q["factor_gflop"] + q["interface_gflop"] for q in per)
        peaks = [b / 1e6 for b in s["peak_memory_bytes_per_rank"]]
        model_crit = (pr["F_s"] + (pr["share"] if s.get("interface_factor") == "mumps" else 0)) / 1e9
        if s.get("interface_factor") in ("dense", "sparse"):
            model_crit = max(model_crit, s["interface_gflop"])  # rank 0's own factor
        print(f"{s['dofs']:>9} {P:>4} {pr['n_G']:>6.0f}/{s['interface_dofs']:<5} {model_crit:>7.1f}/{crit:<8.1f} "
              f"{pr['M'] / 1e6:>6.0f}/{statistics.median(peaks):<7.0f} {pr['M'] / 1e6:>6.0f}/{max(peaks):<7.0f}")
    print()
    big = max(runs, key=lambda s: s["dofs"])
    scale = math.sqrt(a.dofs / big["dofs"])
    contact = a.contact_nodes if a.contact_nodes is not None else big["contact_nodes"] * scale
    c_dofs = m.contact_per_node[id(big)] * contact
    sweeps = a.sweeps if a.sweeps is not None else big["iterations"]
    one = m.predict(a.dofs, 1, c_dofs)
    print(f"prediction: {a.dofs:.3g} dofs on {a.ranks} ranks, {contact:.0f} contact nodes, {sweeps:.0f} sweeps")
    for P in sorted({1, 64, a.ranks}):
        pr = m.predict(a.dofs, P, c_dofs)
        f, sw, loop = times(m, pr, P, sweeps, a)
        crit = pr["F_s"] + pr["share"]
        print(f"  P = {P:>4}: n_s {pr['n_s']:.3g} dofs, dense block b_s {pr['b_s']:.0f}, interface n_G {pr['n_G']:.0f}; "
              f"factor {pr['F_s'] / 1e9:.1f} + interface share {pr['share'] / 1e9:.2f} Gflop "
              f"({crit / one['F_s']:.4f} of one rank's); memory {pr['M'] / 2**30:.2f} GiB per rank; "
              f"factor {f:.1f} s, sweep {sw * 1e3:.2f} ms, loop {loop:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
