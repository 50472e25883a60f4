#!/usr/bin/env python3
"""Tresca variants of Coulomb case files, for held-out checks of the loop's sweep counts.

For every case file of the given directories whose contact has Coulomb friction, runs it
once and writes copies with Tresca friction in its place: the threshold is FACTOR times
the coefficient times the mean pressure of the Coulomb answer's pressed nodes, for each
of --factors. The copies name their mesh by its absolute path, so that they run from
--out.

    python3 run-scripts/tresca_variants.py --bin target/release/contact-par \\
        --out TRESCA HELDOUT SLENDER BEAMS

Each copy is named DIR_CASE_tFACTOR.toml (DIR the source directory's name).
`robustness.sh --cases TRESCA` then runs them.
"""

import argparse
import csv
import os
import re
import subprocess
import sys
import tempfile

COULOMB = re.compile(r'friction = "coulomb"\ncoefficient = ([0-9.eE+-]+)')


def mean_pressure(binary, case):
    """The mean p_n over the pressed nodes of the case's answer."""
    with tempfile.TemporaryDirectory() as out:
        subprocess.run(
            [binary, case, "--threads", "1", "--out", out, "--no-plots", "--quiet"],
            check=True,
            capture_output=True,
        )
        with open(os.path.join(out, "contact.csv")) as f:
            pressed = [float(r["p_n"]) for r in csv.DictReader(f) if float(r["p_n"]) > 0]
    if not pressed:
        raise SystemExit(f"{case}: no node is pressed in its answer; no threshold to scale")
    return sum(pressed) / len(pressed)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default="target/release/contact-par", help="contact-par binary")
    ap.add_argument("--out", required=True, help="directory for the variants")
    ap.add_argument("--factors", default="0.3,1.0", help="threshold factors, comma-separated")
    ap.add_argument("dirs", nargs="+", help="directories of case files")
    args = ap.parse_args()
    factors = [float(f) for f in args.factors.split(",")]
    binary = os.path.abspath(args.bin)
    os.makedirs(args.out, exist_ok=True)
    written = 0
    for d in args.dirs:
        src = os.path.abspath(d)
        for name in sorted(os.listdir(src)):
            if not name.endswith(".toml"):
                continue
            path = os.path.join(src, name)
            text = open(path).read()
            m = COULOMB.search(text)
            mesh = re.search(r'file = "([^"]+)"', text)
            if not m or not mesh:
                continue
            mean = mean_pressure(binary, path)
            text = text.replace(mesh.group(0), f'file = "{os.path.join(src, mesh.group(1))}"')
            for factor in factors:
                threshold = factor * float(m.group(1)) * mean
                body = text.replace(m.group(0), f'friction = "tresca"\nthreshold = {threshold!r}')
                target = os.path.join(args.out, f"{os.path.basename(src)}_{name[:-5]}_t{factor}.toml")
                with open(target, "w") as f:
                    f.write(body)
                written += 1
    print(f"{written} Tresca variants in {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
