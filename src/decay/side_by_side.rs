//! Compensated sums of several bands' frames, four bands side by side.
//!
//! A compensated sum is a chain: each addition waits on the one before. Over one band's 5000
//! frames (10 s at 2 ms) the chain is the whole cost, and a band at a time the processor had
//! nothing else to do while it waited. Here four bands' chains advance together, each exactly
//! as alone (the same additions in the same order, so the same bits), and whatever is left of
//! the longer ones afterwards.

use super::schroeder::CompensatedSum;

/// Sums run side by side.
const LANES: usize = 4;

/// Adds `values[j]`, in order, to `sums[j]` for every j: bit for bit the same as
/// `values[j].iter().for_each(|&x| sums[j].add(x))`.
pub(crate) fn add_each(sums: &mut [CompensatedSum], values: &[&[f64]]) {
    for (sums, values) in sums.chunks_mut(LANES).zip(values.chunks(LANES)) {
        let mut done = 0;
        if let (Ok(sums), Ok(values)) = (
            <&mut [CompensatedSum; LANES]>::try_from(&mut *sums),
            <&[&[f64]; LANES]>::try_from(values),
        ) {
            done = values.iter().map(|v| v.len()).min().unwrap_or(0);
            let mut acc = *sums;
            let [a, b, c, d] = values.map(|v| &v[..done]);
            for (((&xa, &xb), &xc), &xd) in a.iter().zip(b).zip(c).zip(d) {
                acc[0].add(xa);
                acc[1].add(xb);
                acc[2].add(xc);
                acc[3].add(xd);
            }
            *sums = acc;
        }
        for (sum, values) in sums.iter_mut().zip(values) {
            let mut acc = *sum;
            values[done.min(values.len())..]
                .iter()
                .for_each(|&x| acc.add(x));
            *sum = acc;
        }
    }
}

/// The backward compensated integral of each of `values`: `out[j][k]` is the value of the sum
/// of `values[j][k..]` added from the last to the k-th, bit for bit as
/// [`super::schroeder::OnlineSchroeder::edc`] computes it.
pub(crate) fn backward_integrals(values: &[&[f64]]) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = values.iter().map(|v| vec![0.0; v.len()]).collect();
    for (outs, values) in out.chunks_mut(LANES).zip(values.chunks(LANES)) {
        let mut acc = [CompensatedSum::default(); LANES];
        // The common length from each end, four at a time.
        let mut done = 0;
        if let (Ok(outs), Ok(values)) = (
            <&mut [Vec<f64>; LANES]>::try_from(&mut *outs),
            <&[&[f64]; LANES]>::try_from(values),
        ) {
            done = values.iter().map(|v| v.len()).min().unwrap_or(0);
            // Each band's last `done` values and outputs.
            let [va, vb, vc, vd] = values.map(|v| &v[v.len() - done..]);
            let [oa, ob, oc, od] = outs.each_mut().map(|o| {
                let from = o.len() - done;
                &mut o[from..]
            });
            for r in (0..done).rev() {
                acc[0].add(va[r]);
                oa[r] = acc[0].value();
                acc[1].add(vb[r]);
                ob[r] = acc[1].value();
                acc[2].add(vc[r]);
                oc[r] = acc[2].value();
                acc[3].add(vd[r]);
                od[r] = acc[3].value();
            }
        }
        for ((out, values), acc) in outs.iter_mut().zip(values).zip(&mut acc) {
            let rest = values.len() - done.min(values.len());
            for k in (0..rest).rev() {
                acc.add(values[k]);
                out[k] = acc.value();
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bands of every length around the common one, 1 to 9 of them (whole groups of four and
    /// what is left), values spanning 30 decades so that the compensation matters.
    fn bands(count: usize, seed: usize) -> Vec<Vec<f64>> {
        (0..count)
            .map(|j| {
                let len = (seed * 7 + j * 13) % 23;
                (0..len)
                    .map(|k| 10f64.powi(((k * 11 + j * 5 + seed) % 31) as i32 - 15) * 1.37)
                    .collect()
            })
            .collect()
    }

    #[test]
    fn side_by_side_sums_are_each_band_alone() {
        for count in 0..=9 {
            for seed in 0..5 {
                let values = bands(count, seed);
                let slices: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
                // Running sums, from a state that already holds something.
                let start = CompensatedSum { hi: 0.5, lo: 1e-18 };
                let mut together = vec![start; count];
                add_each(&mut together, &slices);
                let backward = backward_integrals(&slices);
                for (j, v) in values.iter().enumerate() {
                    let mut alone = start;
                    v.iter().for_each(|&x| alone.add(x));
                    assert_eq!(together[j], alone, "{count} bands, seed {seed}, band {j}");
                    let mut acc = CompensatedSum::default();
                    let mut curve = vec![0.0; v.len()];
                    for k in (0..v.len()).rev() {
                        acc.add(v[k]);
                        curve[k] = acc.value();
                    }
                    assert_eq!(backward[j], curve, "{count} bands, seed {seed}, band {j}");
                }
            }
        }
    }
}
