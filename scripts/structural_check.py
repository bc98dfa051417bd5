"""Cross-check of `dampscope analyze --bands auto` on structural impact records by an envelope fit.

    pip install numpy scipy
    python3 scripts/structural_check.py [REF_DIR] [--dampscope PATH] [--json OUT] [-- DAMPSCOPE_ARGS...]

REF_DIR is shared/reference (default ../shared/reference); the records are
structural/hrshm_dataset5_pcb_impact_Test_001.csv (51.2 kHz, 2 channels, 1 s) and
structural/hrshm_dataset5_pcb_shock_a0.csv (50 kHz, 1 channel, 0.11 s). Everything after `--`
goes to every `dampscope analyze` call (default: `--front-end octave --range t20`).

dampscope side: `dampscope analyze FILE --bands auto --format jsonl ...`; every row with a
damping ratio is checked.

Independent side, per such row (method unlike dampscope's: no filter bank, no Schroeder curve):
the channel from its peak on, band-limited in the frequency domain to the row's band (one FFT,
a Tukey taper over the outer 10 % of the band on each side, inverse FFT of the one-sided
spectrum = analytic band signal); its envelope |z|; noise = median envelope over the last 20 %
of the record; a straight line fitted to 20 log10 |z| from where it first falls 5 dB below
its peak to where it first falls within 10 dB of the noise (at least 20 dB of decay, else the
mode is reported as not single-slope). D_env = slope (dB/s) · ln 10 / 20 / (2π f), f the band
spectrum's peak. A mode is "single-slope" when that fit has r² ≥ 0.98.

Prints per row: band, f, D dampscope (corrected), D envelope, r² of the envelope fit, Δ %.
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

FILES = [("structural/hrshm_dataset5_pcb_impact_Test_001.csv", 51200),
         ("structural/hrshm_dataset5_pcb_shock_a0.csv", 50000)]
DEFAULT_DS = os.path.join(os.path.dirname(os.path.abspath(__file__)),
                          "..", "target", "release", "dampscope")
DEFAULT_ARGS = ["--front-end", "octave", "--range", "t20"]


def load(path):
    x = np.loadtxt(path, comments="#", delimiter=",")
    return x[:, None] if x.ndim == 1 else x


def envelope_fit(x, fs, lo, hi):
    """(D, f, r2, fitted dB range) of the band lo..hi of x (from its peak), or None."""
    x = x[np.argmax(x ** 2):]
    n = len(x)
    n_fft = 1 << int(np.ceil(np.log2(n)) + 1)
    spec = np.fft.fft(x, n_fft)
    f = np.fft.fftfreq(n_fft, 1 / fs)
    w = np.zeros(n_fft)
    inside = (f >= lo) & (f <= hi)
    taper = 0.1 * (hi - lo)
    u = np.clip(np.minimum(f - lo, hi - f) / taper, 0, 1)
    w[inside] = 0.5 - 0.5 * np.cos(np.pi * u[inside])
    z = np.fft.ifft(2 * spec * w)[:n]
    env_db = 20 * np.log10(np.abs(z) + 1e-300)
    f_peak = f[inside][np.argmax(np.abs(spec[inside]))]
    noise_db = np.median(env_db[int(0.8 * n):])
    k_peak = int(np.argmax(env_db))
    after = env_db[k_peak:]
    below5 = np.nonzero(after < after[0] - 5)[0]
    near_noise = np.nonzero(after < noise_db + 10)[0]
    if below5.size == 0 or near_noise.size == 0:
        return None
    a, b = k_peak + below5[0], k_peak + near_noise[0]
    if b - a < 10 or env_db[a] - env_db[b] < 20:
        return None
    t = np.arange(a, b) / fs
    slope, icpt = np.polyfit(t, env_db[a:b], 1)
    resid = env_db[a:b] - (slope * t + icpt)
    r2 = 1 - resid.var() / env_db[a:b].var()
    d = -slope * np.log(10) / 20 / (2 * np.pi * f_peak)
    return d, f_peak, r2, env_db[a] - env_db[b]


def main():
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else DEFAULT_ARGS
    argv = argv[:argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ref_dir", nargs="?", default="../shared/reference")
    ap.add_argument("--dampscope", default=DEFAULT_DS)
    ap.add_argument("--json", metavar="OUT")
    args = ap.parse_args(argv)
    out = {"dampscope_args": extra, "files": {}}
    print(f"dampscope args: {' '.join(extra)}")
    for rel, fs in FILES:
        path = os.path.join(args.ref_dir, rel)
        x = load(path)
        cmd = [args.dampscope, "analyze", path, "--bands", "auto", "--format", "jsonl"] + extra
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode not in (0, 3):
            sys.exit(f"dampscope failed ({' '.join(cmd)}):\n{p.stderr}")
        rows = [json.loads(line) for line in p.stdout.splitlines() if line.strip()]
        names = sorted({r["channel"] for r in rows})
        print(f"\n### {os.path.basename(rel)}: {len(rows)} rows, "
              f"{sum(r['damping_ratio_corrected'] is not None for r in rows)} with a number\n")
        print("| channel | band Hz | f Hz | D dampscope % | D envelope % | env r² | Δ % | single-slope |")
        print("|---|---|---:|---:|---:|---:|---:|---|")
        checked = []
        for r in rows:
            d_ds = r["damping_ratio_corrected"]
            if d_ds is None:
                continue
            ch = names.index(r["channel"]) if r["channel"] not in ("ch0", "ch1") \
                else int(r["channel"][2:])
            fit = envelope_fit(x[:, ch], fs, r["f_lo"], r["f_hi"])
            if fit is None:
                print(f"| {r['channel']} | {r['f_lo']:.0f}–{r['f_hi']:.0f} | — | {100 * d_ds:.3f} "
                      f"| — | — | — | no (under 20 dB of clean decay) |")
                checked.append({"row": r, "envelope": None})
                continue
            d_env, f_peak, r2, span = fit
            delta = 100 * (d_ds - d_env) / d_env
            single = r2 >= 0.98
            print(f"| {r['channel']} | {r['f_lo']:.0f}–{r['f_hi']:.0f} | {f_peak:.1f} "
                  f"| {100 * d_ds:.3f} | {100 * d_env:.3f} | {r2:.3f} | {delta:+.1f} "
                  f"| {'yes' if single else 'no'} |")
            checked.append({"row": r, "envelope": {"d": d_env, "f_hz": f_peak, "r2": r2,
                                                   "span_db": span, "delta_pct": delta,
                                                   "single_slope": single}})
        single = [c for c in checked if c["envelope"] and c["envelope"]["single_slope"]]
        worst = max((abs(c["envelope"]["delta_pct"]) for c in single), default=None)
        print(f"\nsingle-slope modes: {len(single)}; worst |Δ| among them: "
              + ("—" if worst is None else f"{worst:.1f} %"))
        out["files"][rel] = checked
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
