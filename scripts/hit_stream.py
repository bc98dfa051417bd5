#!/usr/bin/env python3
"""A monitoring stream as it comes: hammer hits at a fixed period on a structure that rings.

Writes raw little-endian f32, interleaved by channel, to standard output, one hit period at a
time (so it can be piped for an hour without holding it). Per channel 3 modes (f 100..1500 Hz,
zeta 0.2..1 %); each hit excites every mode with an amplitude varying +-20 % from hit to hit
and a random phase; the previous hits' tails carry on (superposition, as a real structure does:
the slowest modes ring on for several periods). Sensor noise:
white, `--noise-db` below the channel's first peak.

usage: hit_stream.py [--channels 64] [--fs 4096] [--seconds 3600] [--period 2]
                     [--noise-db 80] [--seed 1] [--truth FILE.json]
"""
import argparse
import json
import sys

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--channels", type=int, default=64)
    ap.add_argument("--fs", type=float, default=4096.0)
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--period", type=float, default=2.0)
    ap.add_argument("--noise-db", type=float, default=80.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--truth", help="write the modes (f, zeta per channel) as JSON here")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    n_modes = 3
    f = rng.uniform(100, 1500, (a.channels, n_modes))
    zeta = rng.uniform(0.002, 0.01, (a.channels, n_modes))
    amp = rng.uniform(0.3, 1.0, (a.channels, n_modes))
    lam = -zeta * 2 * np.pi * f + 1j * 2 * np.pi * f * np.sqrt(1 - zeta**2)
    if a.truth:
        with open(a.truth, "w") as fh:
            json.dump({"f_hz": f.tolist(), "zeta": zeta.tolist()}, fh)
    n = int(round(a.period * a.fs))
    t = np.arange(n) / a.fs
    basis = np.exp(lam[:, :, None] * t[None, None, :])  # (ch, mode, n)
    step = np.exp(lam * a.period)
    state = np.zeros((a.channels, n_modes), complex)
    peak = None
    hits = int(np.ceil(a.seconds / a.period))
    out = sys.stdout.buffer
    for _ in range(hits):
        state = state + amp * rng.uniform(0.8, 1.2, amp.shape) * np.exp(
            1j * rng.uniform(0, 2 * np.pi, amp.shape))
        x = np.einsum("cm,cmn->cn", state, basis).imag
        if peak is None:
            peak = np.abs(x).max(axis=1, keepdims=True)
        x += peak * 10 ** (-a.noise_db / 20) * rng.standard_normal(x.shape)
        state = state * step
        try:
            out.write(np.ascontiguousarray(x.T, dtype="<f4").tobytes())
        except BrokenPipeError:
            return


if __name__ == "__main__":
    main()
