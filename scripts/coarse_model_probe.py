#!/usr/bin/env python3
"""Probe of `diagnose` with a coarse model against recordings unlike it.

The truth is the plate (LX x LY x H m, default 1 x 1.5 x 0.02 aluminium, pinned on y0 and y1)
on a finer mesh (FINE, default 36,54) with a point mass at a random place (0.5-4 kg per 81 kg of
plate; none with CONTROL=1), recorded at 88 sensors between the nodes with noise 50 dB under the
mean signal power (seed = case + 1); the model is the same plate on COARSE (default 12,18)
without the mass. Prints per case the truth and what `diagnose --fmax FMAX` (default 400) found.

SIM=kirchhoff takes the recordings from scripts/kirchhoff_sim.py (thin-plate theory, no mesh)
instead of `dampscope simulate` on FINE.

usage: CONTROL=1 LX=1.5 LY=2 H=0.01 FMAX=200 TAG=m SIM=kirchhoff \\
       scripts/coarse_model_probe.py BIN SEED N [FINE] [COARSE]
Files go to /tmp/mp/<TAG><SEED>/ (TAG default "s").
"""
import json, os, random, subprocess, sys, shutil
BIN = sys.argv[1]; SEED = int(sys.argv[2]); N = int(sys.argv[3])
fine = sys.argv[4] if len(sys.argv) > 4 else "36,54"
coarse = sys.argv[5] if len(sys.argv) > 5 else "12,18"
lx, ly, h = float(os.environ.get("LX", 1.0)), float(os.environ.get("LY", 1.5)), float(os.environ.get("H", 0.02))
FMAX = os.environ.get("FMAX", "400")
rng = random.Random(SEED)
def model(path, nx, ny, mass=None, sensors=None, fmax=500.0):
    s = f"""[plate]
lx = {lx}
ly = {ly}
thickness = {h}
[mesh]
nx = {nx}
ny = {ny}
nz = 2
[material]
youngs_modulus = 7.0e10
poisson = 0.34
density = 2700.0
loss_factor = 0.05
[supports]
pinned_edges = ["y0", "y1"]
[excitation]
x = 0.07
y = 0.09
dir = "z"
force = 1.0
[output]
fmax = {fmax}
df = 0.3333333333333333
"""
    s += f'sensors = {{ file = "{sensors}" }}\n' if sensors else "sensors = { nx = 9, ny = 13 }\n"
    if mass:
        s += f"[[point_mass]]\nx = {mass[0]}\ny = {mass[1]}\nmass = {mass[2]}\n"
    open(path, "w").write(s)
fnx, fny = map(int, fine.split(",")); cnx, cny = map(int, coarse.split(","))
work = f"/tmp/mp/{os.environ.get('TAG', 's')}{SEED}"; os.makedirs(work, exist_ok=True)
sens = f"{work}/sensors.csv"
with open(sens, "w") as f:
    f.write("id,x,y,dir\n")
    k = 0
    for j in range(11):
        for i in range(8):
            x = 0.05 + (lx - 0.1) * (i + 0.37) / 8; y = 0.05 + (ly - 0.1) * (j + 0.41) / 11
            f.write(f"s{k:03},{x:.4f},{y:.4f},z\n"); k += 1
cm = f"{work}/coarse.toml"; model(cm, cnx, cny)
for case in range(N):
    x = round(rng.uniform(0.1, lx - 0.1), 3); y = round(rng.uniform(0.15, ly - 0.15), 3)
    m = round(rng.uniform(0.5, 4.0) * lx * ly * h / 0.03, 2)
    if os.environ.get('CONTROL'): m = 0.0
    tm = f"{work}/truth{case}.toml"; model(tm, fnx, fny, (x, y, m) if m else None, sens)
    rec = f"{work}/rec{case}"; shutil.rmtree(rec, ignore_errors=True)
    if os.environ.get("SIM") == "kirchhoff":
        # Another plate theory and discretisation (scripts/kirchhoff_sim.py: thin-plate
        # Rayleigh-Ritz, no mesh); its noise is also defined on the mean signal power.
        here = os.path.dirname(os.path.abspath(__file__))
        subprocess.run([sys.executable, f"{here}/kirchhoff_sim.py", tm, "--out", rec,
                        "--snr-db", "50", "--seed", str(case + 1), "--sensors", sens],
                       check=True, capture_output=True)
    else:
        subprocess.run([BIN, "simulate", "--model", tm, "--out", rec, "--snr-db", "50",
                        "--snr-definition", "mean-power", "--seed", str(case + 1)],
                       check=True, capture_output=True)
    out = f"{work}/diag{case}"
    r = subprocess.run([BIN, "diagnose", rec, "--model", cm, "--out", out, "--fmax", FMAX],
                       capture_output=True, text=True)
    try:
        d = json.load(open(f"{out}/diagnosis.json"))
    except Exception:
        print(case, "FAIL", r.stderr[-300:]); continue
    fs = [(f["kind"], f.get("point"), f.get("parameters")) for f in d["findings"]]
    found = [f for f in d["findings"] if f["kind"] == "added_mass"]
    if found:
        p = found[0]["point"]; fm = found[0]["parameters"]["mass_kg"]
        print(f"{case} true ({x},{y}) {m} kg -> ({p['x']:.2f},{p['y']:.2f}) {fm:.2f} kg "
              f"err {100*(fm/m-1) if m else 0:+.0f}% off {((p['x']-x)**2+(p['y']-y)**2)**.5:.2f} m; others "
              f"{[k for k,_,_ in fs if k!='added_mass']}", flush=True)
    else:
        print(f"{case} true ({x},{y}) {m} kg -> no mass; {[(k,pp) for k,_,pp in fs]}", flush=True)
