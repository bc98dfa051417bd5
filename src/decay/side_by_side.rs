//! Compensated sums of several bands' frames, the bands side by side in vector lanes.
//!
//! A compensated sum is a chain: each addition waits on the one before. Over one band's 5000
//! frames (10 s at 2 ms) the chain is the whole cost, and a band at a time the processor had
//! nothing else to do while it waited. Here up to eight bands' chains (four without AVX-512)
//! advance together in one vector register, each exactly as alone (the same operations in the
//! same order, the branch of [`CompensatedSum::add`] a lane-wise select, so the same bits), and
//! whatever is left of the longer ones afterwards, band by band.

use super::schroeder::{CompensatedSum, PooledCurve};
use crate::frontend::simd::Isa;

/// [`CompensatedSum::add`] in every lane.
#[inline(always)]
fn add_lanes<const L: usize>(hi: &mut [f64; L], lo: &mut [f64; L], x: [f64; L]) {
    for l in 0..L {
        let t = hi[l] + x[l];
        let big = (hi[l] - t) + x[l];
        let small = (x[l] - t) + hi[l];
        lo[l] += if hi[l].abs() >= x[l].abs() {
            big
        } else {
            small
        };
        hi[l] = t;
    }
}

/// Runs `$body::<L>(first, values)` with the widest lanes this CPU has (8 with AVX-512, else 4).
macro_rules! with_lanes {
    ($body:ident, $first:expr => $ty:ty, $values:expr) => {{
        match Isa::detect() {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => {
                #[target_feature(enable = "avx512f")]
                unsafe fn wide(first: $ty, values: &[&[f64]]) {
                    $body::<8>(first, values)
                }
                // SAFETY: `Isa::detect` found AVX-512F on this CPU.
                unsafe { wide($first, $values) }
            }
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma => {
                #[target_feature(enable = "avx2")]
                unsafe fn narrow(first: $ty, values: &[&[f64]]) {
                    $body::<4>(first, values)
                }
                // SAFETY: `Isa::detect` found AVX2 on this CPU.
                unsafe { narrow($first, $values) }
            }
            _ => $body::<4>($first, $values),
        }
    }};
}

/// Adds `values[j]`, in order, to `sums[j]` for every j: bit for bit the same as
/// `values[j].iter().for_each(|&x| sums[j].add(x))`.
pub(crate) fn add_each(sums: &mut [CompensatedSum], values: &[&[f64]]) {
    with_lanes!(add_each_in, sums => &mut [CompensatedSum], values)
}

#[inline(always)]
fn add_each_in<const L: usize>(sums: &mut [CompensatedSum], values: &[&[f64]]) {
    for (sums, values) in sums.chunks_mut(L).zip(values.chunks(L)) {
        let n = sums.len();
        // A lone band gains nothing from lanes.
        let done = if n > 1 {
            values.iter().map(|v| v.len()).min().unwrap_or(0)
        } else {
            0
        };
        if done > 0 {
            // Lanes past the group's bands repeat its last band (and are dropped).
            let src: [&[f64]; L] = std::array::from_fn(|l| &values[l.min(n - 1)][..done]);
            let mut hi: [f64; L] = std::array::from_fn(|l| sums[l.min(n - 1)].hi);
            let mut lo: [f64; L] = std::array::from_fn(|l| sums[l.min(n - 1)].lo);
            // `k` indexes every lane's slice (`L` of them, no zip for that).
            #[allow(clippy::needless_range_loop)]
            for k in 0..done {
                add_lanes(&mut hi, &mut lo, std::array::from_fn(|l| src[l][k]));
            }
            for (l, sum) in sums.iter_mut().enumerate() {
                *sum = CompensatedSum {
                    hi: hi[l],
                    lo: lo[l],
                };
            }
        }
        for (sum, values) in sums.iter_mut().zip(values) {
            let mut acc = *sum;
            values[done..].iter().for_each(|&x| acc.add(x));
            *sum = acc;
        }
    }
}

/// The backward compensated integral of each of `values`: `out[j][k]` is the value of the sum
/// of `values[j][k..]` added from the last to the k-th, bit for bit as
/// [`super::schroeder::OnlineSchroeder::edc`] computes it.
pub(crate) fn backward_integrals(values: &[&[f64]]) -> Vec<PooledCurve> {
    let mut out: Vec<PooledCurve> = values.iter().map(|v| PooledCurve::zeros(v.len())).collect();
    let mut outs: Vec<&mut [f64]> = out.iter_mut().map(|o| o.as_mut_slice()).collect();
    with_lanes!(backward_in, &mut outs => &mut [&mut [f64]], values);
    out
}

/// [`backward_integrals`] into `outs` (each as long as its values).
#[inline(always)]
fn backward_in<const L: usize>(outs: &mut [&mut [f64]], values: &[&[f64]]) {
    for (outs, values) in outs.chunks_mut(L).zip(values.chunks(L)) {
        let n = outs.len();
        let mut hi = [0.0; L];
        let mut lo = [0.0; L];
        // The common length from each end, in lanes.
        let done = if n > 1 {
            values.iter().map(|v| v.len()).min().unwrap_or(0)
        } else {
            0
        };
        if done > 0 {
            let src: [&[f64]; L] = std::array::from_fn(|l| {
                let v = values[l.min(n - 1)];
                &v[v.len() - done..]
            });
            for r in (0..done).rev() {
                add_lanes(&mut hi, &mut lo, std::array::from_fn(|l| src[l][r]));
                for (l, out) in outs.iter_mut().enumerate() {
                    let at = out.len() - done + r;
                    out[at] = hi[l] + lo[l];
                }
            }
        }
        for (l, (out, values)) in outs.iter_mut().zip(values).enumerate() {
            let mut acc = CompensatedSum {
                hi: hi[l],
                lo: lo[l],
            };
            let rest = values.len() - done.min(values.len());
            for k in (0..rest).rev() {
                acc.add(values[k]);
                out[k] = acc.value();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bands of every length around the common one, values spanning 30 decades so that the
    /// compensation matters, of both signs in some bands (both branches of the addition).
    fn bands(count: usize, seed: usize) -> Vec<Vec<f64>> {
        (0..count)
            .map(|j| {
                let len = (seed * 7 + j * 13) % 23;
                (0..len)
                    .map(|k| {
                        let sign = if (j + seed).is_multiple_of(3) && k % 4 == 1 {
                            -1.0
                        } else {
                            1.0
                        };
                        sign * 10f64.powi(((k * 11 + j * 5 + seed) % 31) as i32 - 15) * 1.37
                    })
                    .collect()
            })
            .collect()
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// Every lane width and the dispatched form against each band summed alone: 0 to 17 bands
    /// (whole groups of four and eight, and what is left).
    #[test]
    fn side_by_side_sums_are_each_band_alone() {
        type Adder = fn(&mut [CompensatedSum], &[&[f64]]);
        type Integrator = fn(&mut [&mut [f64]], &[&[f64]]);
        let adders: [(&str, Adder); 3] = [
            ("dispatched", add_each),
            ("4 lanes", add_each_in::<4>),
            ("8 lanes", add_each_in::<8>),
        ];
        let dispatched: Integrator = |outs, values| {
            let curves = backward_integrals(values);
            for (o, c) in outs.iter_mut().zip(curves) {
                o.copy_from_slice(&c);
            }
        };
        let integrators: [(&str, Integrator); 3] = [
            ("dispatched", dispatched),
            ("4 lanes", backward_in::<4>),
            ("8 lanes", backward_in::<8>),
        ];
        for count in 0..=17 {
            for seed in 0..5 {
                let values = bands(count, seed);
                let slices: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
                // Running sums, from a state that already holds something.
                let start = CompensatedSum { hi: 0.5, lo: 1e-18 };
                for ((name, add), (_, integrate)) in adders.iter().zip(&integrators) {
                    let mut together = vec![start; count];
                    add(&mut together, &slices);
                    let mut backward: Vec<Vec<f64>> =
                        values.iter().map(|v| vec![f64::NAN; v.len()]).collect();
                    let mut outs: Vec<&mut [f64]> =
                        backward.iter_mut().map(|b| b.as_mut_slice()).collect();
                    integrate(&mut outs, &slices);
                    for (j, v) in values.iter().enumerate() {
                        let mut alone = start;
                        v.iter().for_each(|&x| alone.add(x));
                        let at = format!("{name}: {count} bands, seed {seed}, band {j}");
                        assert_eq!(
                            bits(&[together[j].hi, together[j].lo]),
                            bits(&[alone.hi, alone.lo]),
                            "{at}"
                        );
                        let mut acc = CompensatedSum::default();
                        let mut curve = vec![0.0; v.len()];
                        for k in (0..v.len()).rev() {
                            acc.add(v[k]);
                            curve[k] = acc.value();
                        }
                        assert_eq!(bits(&backward[j]), bits(&curve), "{at}");
                    }
                }
            }
        }
    }
}
