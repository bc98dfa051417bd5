"""Cross-check for tests/suite/filterbank_octave.rs: pyrato's own per-octave T20/T30 on the noisy
analytic RIR (shared/reference/pyrato_tests/analytic_rir_psnr50_2D.csv), and the same RIR
regenerated without noise.

    pip install pyrato pyfar matplotlib
    python3 scripts/pyrato_octave_psnr.py [path/to/shared/reference]

Prints, per octave band (63 Hz ... 1 kHz) and channel (true T60 1 s and 2 s), pyrato's T20 and
T30 with Chu + Lundeby noise handling, and writes the noise-free RIR as CSV (`# fs=3000`) to
/tmp/analytic_rir_clean.csv so that `dampscope analyze /tmp/analytic_rir_clean.csv
--front-end octave --bands octave --range t20` can show the bank is exact without noise.
"""
import sys
import warnings

import numpy as np
import pyfar as pf
import pyrato
from pyrato.analytic import rectangular_room_rigid_walls

warnings.filterwarnings("ignore")
ref_dir = sys.argv[1] if len(sys.argv) > 1 else "../shared/reference"
noisy = np.loadtxt(f"{ref_dir}/pyrato_tests/analytic_rir_psnr50_2D.csv", delimiter=",")
fs = 3000

# The generator's parameters (see shared/reference/README.md), jointly normalised.
clean = []
for t60 in (1.0, 2.0):
    rir, _ = rectangular_room_rigid_walls(
        [1, 1, 1], [0.2, 0.3, 0.4], [0.5, 0.6, 0.7], t60, 1e3,
        samplingrate=fs, speed_of_sound=343.9, n_samples=2**14)
    clean.append(np.asarray(rir.time).ravel())
clean = np.array(clean)
clean /= np.abs(clean).max()
residual = noisy - clean * (noisy * clean).sum(1, keepdims=True) / (clean**2).sum(1, keepdims=True)
print("noise std per channel:", residual.std(1), "-> broadband peak-SNR dB:",
      20 * np.log10(np.abs(noisy).max(1) / residual.std(1)))
np.savetxt("/tmp/analytic_rir_clean.csv", clean.T, delimiter=",", header="fs=3000")

bands = pf.dsp.filter.fractional_octave_bands(pf.Signal(noisy, fs), 1, frequency_range=(63, 1000))
centres = pf.dsp.filter.fractional_octave_frequencies(1, (63, 1000))[0]
for rng in ("T20", "T30"):
    for b, fc in enumerate(centres):
        try:
            edc = pyrato.edc.energy_decay_curve_chu_lundeby(
                bands[b], smoothing_parameter="broadband", is_energy=False,
                time_shift=True, channel_independent=False, normalize=True)
            t = np.asarray(pyrato.parameters.reverberation_time_linear_regression(edc, rng)).ravel()
            print(f"pyrato chu_lundeby {rng} {fc:6.0f} Hz: {np.round(t, 4)}")
        except Exception as e:  # pyrato fails where the band holds only noise
            print(f"pyrato chu_lundeby {rng} {fc:6.0f} Hz: error {e}")
