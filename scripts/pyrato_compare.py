"""Cross-check of dampscope against pyrato on measured room impulse responses, per octave band.

    pip install pyrato pyfar numpy scipy
    python3 scripts/pyrato_compare.py [REF_DIR] [--pyrato-order 14] [--json OUT] \
        [--dampscope PATH] [-- DAMPSCOPE_ARGS...]

REF_DIR is shared/reference (default ../shared/reference).  Everything after `--` is passed
verbatim to every `dampscope analyze` call, e.g. `-- --filter-direction forward`.

Files: rir/living_room_1.wav, rir/ir_sportscentre_omni.wav and
pyrato_tests/room_impulse_response_with_noise.csv (fs = 48000 Hz, given as --fs).

pyrato side, per octave band 63 Hz .. 8 kHz (bands whose upper edge is below fs/2): pyfar's
fractional_octave_bands (Butterworth, order --pyrato-order), then, band by band,
pyrato.edc.energy_decay_curve_chu_lundeby (time_shift=True, normalize=True, noise_level='auto',
smoothing_parameter = the band's centre frequency as pyrato's docstring advises for octave
bands) and pyrato.parameters.reverberation_time_linear_regression for EDT, T20 and T30.
Each band is its own one-channel call, so time shift and normalisation are per band.

dampscope side: `dampscope analyze FILE --front-end octave --bands octave --range R
--format jsonl` for R in edt, t20, t30; the range's number is the `t60_s` column (the 60 dB
time extrapolated from that range; empty when a flag withholds it).

Prints a markdown table per file (Δ% = 100 (dampscope − pyrato) / pyrato) with the median |Δ|
per quantity and the worst band.
"""
import argparse
import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pyfar as pf
import pyrato
from scipy.io import wavfile

FILES = [("rir/living_room_1.wav", None),
         ("rir/ir_sportscentre_omni.wav", None),
         ("pyrato_tests/room_impulse_response_with_noise.csv", 48000)]
QUANTITIES = [("EDT", "edt"), ("T20", "t20"), ("T30", "t30")]  # (pyrato T=, dampscope --range)
DEFAULT_DS = os.path.join(os.path.dirname(os.path.abspath(__file__)),
                          "..", "target", "release", "dampscope")


def load(path, fs):
    if path.endswith(".wav"):
        fs, x = wavfile.read(path)
        if x.dtype.kind == "i":
            x = x / float(np.iinfo(x.dtype).max + 1)
        x = x if x.ndim == 1 else x[:, 0]
    else:
        x = np.loadtxt(path, comments="#")
    return np.asarray(x, dtype=float), fs


def pyrato_times(x, fs, order):
    """{nominal Hz: {'EDT': s, 'T20': s, 'T30': s, 'warnings': [...]}} (None where pyrato fails)."""
    nominal = pf.constants.fractional_octave_frequencies_nominal(1, (63, 8000))
    exact, _, upper = pf.constants.fractional_octave_frequencies_exact(1, (63, 8000))
    keep = upper < fs / 2
    nominal, exact = nominal[keep], exact[keep]
    bands = pf.dsp.filter.fractional_octave_bands(
        pf.Signal(x, fs), 1, frequency_range=(nominal[0], nominal[-1]), order=order)
    out = {}
    for b, (fn, fc) in enumerate(zip(nominal, exact)):
        res = {"warnings": []}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            edc = pyrato.edc.energy_decay_curve_chu_lundeby(
                bands[b], smoothing_parameter=fc, time_shift=True, normalize=True)
            for name, _ in QUANTITIES:
                try:
                    t = float(np.ravel(
                        pyrato.parameters.reverberation_time_linear_regression(edc, T=name))[0])
                    res[name] = t if np.isfinite(t) and t > 0 else None
                except ValueError as e:  # all-NaN EDC: Lundeby found no intersection
                    res[name] = None
                    res["warnings"].append(f"{name}: {e}")
        res["warnings"] += sorted({str(w.message).splitlines()[0] for w in caught
                                   if not issubclass(w.category, DeprecationWarning)})
        out[float(fn)] = res
    return out


def dampscope_times(ds, path, fs, extra):
    """{nominal Hz: {'EDT': s|None, ..., 'flags': {'EDT': [...], ...}}} from decay 0, channel 0."""
    out = {}
    for name, rng in QUANTITIES:
        cmd = [ds, "analyze", path, "--front-end", "octave", "--bands", "octave",
               "--range", rng, "--format", "jsonl"] + (["--fs", str(fs)] if fs else []) + extra
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"dampscope failed ({' '.join(cmd)}):\n{p.stderr}")
        rows = [json.loads(line) for line in p.stdout.splitlines() if line.strip()]
        if any(r["decay"] != 0 for r in rows):
            print(f"note: dampscope split {path} into several decays; using decay 0",
                  file=sys.stderr)
        for r in rows:
            if r["decay"] == 0 and r["channel"] == rows[0]["channel"]:
                band = out.setdefault(float(r["f_nominal"]), {"flags": {}})
                band[name] = r["t60_s"]
                band["flags"][name] = r["flags"]
    return out


def fmt_flags(flags):
    """Flags common to all ranges plainly, range-specific ones as RANGE:flag."""
    common = set.intersection(*(set(f) for f in flags.values())) if flags else set()
    parts = sorted(common)
    for name, f in flags.items():
        parts += [f"{name}:{x}" for x in f if x not in common]
    return ", ".join(parts)


def compare(label, py, ds):
    rows, deltas = [], {name: [] for name, _ in QUANTITIES}
    for fn in sorted(py):
        p, d = py[fn], ds.get(fn, {"flags": {}})
        row = {"band_hz": fn, "pyrato": {}, "dampscope": {}, "delta_pct": {},
               "flags": d["flags"], "pyrato_warnings": p["warnings"]}
        for name, _ in QUANTITIES:
            a, b = p.get(name), d.get(name)
            row["pyrato"][name], row["dampscope"][name] = a, b
            row["delta_pct"][name] = 100 * (b - a) / a if a and b is not None else None
            if row["delta_pct"][name] is not None:
                deltas[name].append((abs(row["delta_pct"][name]), fn))
        rows.append(row)

    s = lambda v: "—" if v is None else f"{v:.3f}"
    pct = lambda v: "—" if v is None else f"{v:+.1f}"
    print(f"\n### {label}\n")
    print("| band Hz | pyrato EDT | ds EDT | Δ% | pyrato T20 | ds T20 | Δ% | pyrato T30 | ds T30 "
          "| Δ% | dampscope flags |")
    print("|---:" * 10 + "|---|")
    for r in rows:
        cells = [f"{r['band_hz']:g}"]
        for name, _ in QUANTITIES:
            cells += [s(r["pyrato"][name]), s(r["dampscope"][name]), pct(r["delta_pct"][name])]
        print("| " + " | ".join(cells + [fmt_flags(r["flags"])]) + " |")
    summary = {}
    for name, _ in QUANTITIES:
        v = deltas[name]
        summary[name] = {"median_abs_delta_pct": float(np.median([a for a, _ in v])) if v else None,
                         "n": len(v)}
    worst = max(((a, fn, name) for name, _ in QUANTITIES for a, fn in deltas[name]), default=None)
    summary["worst"] = {"band_hz": worst[1], "quantity": worst[2], "abs_delta_pct": worst[0]} \
        if worst else None
    print("\nmedian |Δ|: " + ", ".join(
        f"{name} {s2['median_abs_delta_pct']:.1f} % (n={s2['n']})" if s2["n"] else f"{name} —"
        for name, s2 in ((n, summary[n]) for n, _ in QUANTITIES)))
    if worst:
        print(f"worst band: {worst[1]:g} Hz, {worst[2]} |Δ| = {worst[0]:.1f} %")
    for r in rows:
        for w in r["pyrato_warnings"]:
            print(f"pyrato warning, {r['band_hz']:g} Hz: {w}")
    return {"bands": rows, "summary": summary}


def main():
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ref_dir", nargs="?", default="../shared/reference")
    ap.add_argument("--pyrato-order", type=int, default=14, help="pyfar Butterworth order")
    ap.add_argument("--json", metavar="OUT", help="write all numbers here")
    ap.add_argument("--dampscope", default=DEFAULT_DS, help="dampscope binary")
    args = ap.parse_args(argv)

    print(f"pyrato {pyrato.__version__}, pyfar {pf.__version__}, pyfar order {args.pyrato_order}; "
          f"dampscope extra args: {' '.join(extra) or '(none)'}")
    result = {"pyrato_order": args.pyrato_order, "dampscope_args": extra, "files": {}}
    for rel, fs_given in FILES:
        path = os.path.join(args.ref_dir, rel)
        x, fs = load(path, fs_given)
        py = pyrato_times(x, fs, args.pyrato_order)
        ds = dampscope_times(args.dampscope, path, fs_given, extra)
        label = f"{os.path.basename(rel)} (fs {fs} Hz, {len(x) / fs:.2f} s)"
        result["files"][rel] = {"fs": fs, **compare(label, py, ds)}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
