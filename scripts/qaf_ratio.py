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

# Every sample where phenylalanine dominates the band, by concentration: its signal per µM
# at the excitation maximum (255 nm) and the shape of its excitation band (240 over
# 255 nm). The inner filter of a concentrated sample lowers both smoothly with its
# absorbance, whatever the scale of the signal; a sample off that curve in both is off in
# its concentration, not in the model.
def band(cells, x):
    j = ex.index(x)
    return sum(cells[l][j] for l in cells if 280 <= l <= 292 and not math.isnan(cells[l][j]))
print("sample  phenylalanine µM  signal/µM at 255 nm  shape 240/255 nm")
rows = []
for name in conc:
    if name == "sample" or float(conc[name][phe]) < 700:
        continue
    try:
        _, cells = read(name)
    except FileNotFoundError:
        continue
    c = float(conc[name][phe])
    rows.append((c, name, band(cells, 255.0) / c, band(cells, 240.0) / band(cells, 255.0)))
for c, name, per, shape in sorted(rows):
    print(f"{name:6s}  {c:16.0f}  {per:19.4f}  {shape:16.3f}")
