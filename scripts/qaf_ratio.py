#!/usr/bin/env python3
"""Model-free check of Dorrit's QAF: its raw cells over QAG's and QAH's at 240–260 nm
excitation, emission 270–300 nm (phenylalanine's band), next to the concentration ratios."""
import csv, math, sys
d = sys.argv[1] if len(sys.argv) > 1 else "../shared/data/eem-instrument/dorrit"
def read(name):
    rows = list(csv.reader(open(f"{d}/{name}.csv")))
    ex = [float(x) for x in rows[0][1:]]
    return ex, {float(r[0]): [float(x) for x in r[1:]] for r in rows[1:]}
conc = {r[0]: r[1:] for r in csv.reader(open(f"{d}/concentrations.csv"))}
head = conc["sample"]
phe = head.index(next(h for h in head if h.startswith("phenylalanine")))
ex, qaf = read("QAF")
for other in ("QAG", "QAH"):
    _, o = read(other)
    for j, x in enumerate(ex):
        if 240 <= x <= 260:
            a = sum(qaf[l][j] for l in qaf if 270 <= l <= 300 and not math.isnan(qaf[l][j]))
            b = sum(o[l][j] for l in o if 270 <= l <= 300 and not math.isnan(o[l][j]))
            print(f"ex {x:.0f} nm: QAF/{other} raw signal {a / b:.3f}")
    print(f"phenylalanine QAF/{other}: {float(conc['QAF'][phe]) / float(conc[other][phe]):.3f}")
