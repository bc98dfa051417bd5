//! Six-decimal number cells of the CSV table, written without the general float formatter.
//!
//! `format!("{x:.6}")` rounds the exact binary value of `x` to six decimals (ties to even) with
//! an arbitrary-precision fallback, and allocates a string per cell: the twenty numbers of a
//! row were most of the main thread's time in a short run (384 rows of a 64-channel octave
//! analysis, formatted while both cores finished channels). Here the same decimal comes from
//! integer arithmetic for every value below 2^52 / 10^6 (4.5 · 10^9) in magnitude and not
//! tiny; anything else takes `format!`. The test holds it to `format!` digit for digit.

/// Largest |x| taken here: x · 10^6 stays below 2^52, where the product's rounding error is
/// below half a unit of the last place and every integer is exact.
const MAX_FAST: f64 = 4.5e9;

/// Smallest non-zero |x| taken here: the product's error term stays a normal number (exact).
const MIN_FAST: f64 = 1e-290;

/// `x` with six decimals into `out`, exactly as `format!("{x:.6}")` writes it.
pub fn write_fixed6(x: f64, out: &mut String) {
    let a = x.abs();
    if !(a <= MAX_FAST && (a >= MIN_FAST || a == 0.0)) {
        // Non-finite, huge or tiny: the general formatter.
        use std::fmt::Write;
        let _ = write!(out, "{x:.6}");
        return;
    }
    let units = millionths(a);
    if x.is_sign_negative() {
        out.push('-');
    }
    let (whole, frac) = (units / 1_000_000, units % 1_000_000);
    let mut digits = [0u8; 24];
    let mut at = digits.len();
    // The six decimals, then the integer part (at least one digit).
    let mut f = frac;
    for _ in 0..6 {
        at -= 1;
        digits[at] = b'0' + (f % 10) as u8;
        f /= 10;
    }
    at -= 1;
    digits[at] = b'.';
    let mut w = whole;
    loop {
        at -= 1;
        digits[at] = b'0' + (w % 10) as u8;
        w /= 10;
        if w == 0 {
            break;
        }
    }
    // ASCII digits and a point.
    out.push_str(std::str::from_utf8(&digits[at..]).unwrap_or_default());
}

/// a · 10^6 rounded to the nearest integer, ties to even, for 0 ≤ a ≤ [`MAX_FAST`] (a normal
/// product, or 0): from the rounded product p and its exact error e = a · 10^6 − p.
fn millionths(a: f64) -> u64 {
    let p = a * 1e6;
    // Exact: the error of a product of normal numbers is representable (no underflow here).
    let e = a.mul_add(1e6, -p);
    let floor = p.floor();
    // The exact product is floor + r + e. p's fraction r is a multiple of ulp(p) ≤ 2^-1 and
    // |e| ≤ ulp(p) / 2, so unless r is exactly one half, r + e lies on the same side of one half
    // as r; r = 0 leaves the product within |e| of `floor`, which it rounds to.
    let r = p - floor;
    let up = if r > 0.5 {
        true
    } else if r < 0.5 {
        false
    } else if e != 0.0 {
        e > 0.0
    } else {
        // An exact tie: to the even neighbour.
        floor % 2.0 != 0.0
    };
    floor as u64 + u64::from(up)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(x: f64) {
        let mut got = String::new();
        write_fixed6(x, &mut got);
        assert_eq!(got, format!("{x:.6}"), "x = {x:e} ({:#x})", x.to_bits());
    }

    /// Digit for digit `format!`'s: exact ties (odd multiples of 2^-7, whose millionths end in
    /// .5), values a hair either side of every tie, powers of ten and their neighbours, signed
    /// zeros, the edges of the fast range, non-finite values, and a million pseudo-random bit
    /// patterns over the magnitudes a table holds.
    #[test]
    fn cells_are_formats_own() {
        for q in (1..20_000u64).step_by(2) {
            for k in 1..=7 {
                let x = q as f64 / f64::from(1u32 << k);
                for v in [
                    x,
                    -x,
                    f64::from_bits(x.to_bits() + 1),
                    f64::from_bits(x.to_bits() - 1),
                ] {
                    check(v);
                }
            }
        }
        for e in -12..=10 {
            let x = 10f64.powi(e);
            for v in [
                x,
                f64::from_bits(x.to_bits() + 1),
                f64::from_bits(x.to_bits() - 1),
            ] {
                check(v);
                check(-v);
                check(v * 0.5);
                check(v * 1.5);
            }
        }
        for v in [
            0.0,
            -0.0,
            MAX_FAST,
            -MAX_FAST,
            f64::from_bits(MAX_FAST.to_bits() + 1),
            MIN_FAST,
            f64::from_bits(MIN_FAST.to_bits() - 1),
            5e-7,
            f64::from_bits(5e-7f64.to_bits() - 1),
            5.000000000000001e-7,
            1e-300,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            0.1234565,
            2.5e-6,
            999999.9999995,
        ] {
            check(v);
            check(-v);
        }
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for i in 0..1_000_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            // Exponents from 2^-30 to 2^34 (10^-9 … 1.7 · 10^10), any mantissa and sign.
            let exponent = 1023 - 30 + (state >> 58) % 65;
            let bits = (state & 0x800F_FFFF_FFFF_FFFF) | (exponent << 52);
            check(f64::from_bits(bits));
            if i % 4 == 0 {
                // Short decimals (the table's usual values), a few ulps off.
                let x = (state % 100_000_000) as f64 / 1e5;
                check(f64::from_bits(x.to_bits().wrapping_add(state >> 61)));
            }
        }
    }
}
