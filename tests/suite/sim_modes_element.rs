//! Pure bending of a slender cantilever of one element layer: the incompatible-mode hexahedron
//! matches Euler–Bernoulli, the plain trilinear hexahedron (oracle of locking) does not.

use dampscope::sim::element::{elasticity, hex8_incompatible_stiffness, hex8_plain_stiffness};
use nalgebra::{DMatrix, DVector};

/// Tip deflection of a cantilever (L × b × h, ne elements along x, one across and through)
/// under an end moment applied as a couple of axial nodal forces.
fn tip_deflection(incompatible: bool, ne: usize, l: f64, b: f64, h: f64, moment: f64) -> f64 {
    let c = elasticity(2.0e11, 0.0);
    let dx = l / ne as f64;
    let coords = [
        [0.0, 0.0, 0.0],
        [dx, 0.0, 0.0],
        [dx, b, 0.0],
        [0.0, b, 0.0],
        [0.0, 0.0, h],
        [dx, 0.0, h],
        [dx, b, h],
        [0.0, b, h],
    ];
    let ke = if incompatible {
        hex8_incompatible_stiffness(&coords, &c, 0).unwrap()
    } else {
        hex8_plain_stiffness(&coords, &c, 0).unwrap()
    };
    // Nodes (i, j, k): i along x, j across, k through the thickness.
    let node = |i: usize, j: usize, k: usize| (k * 2 + j) * (ne + 1) + i;
    let n = 3 * 4 * (ne + 1);
    let mut k = DMatrix::<f64>::zeros(n, n);
    for e in 0..ne {
        let nodes = [
            node(e, 0, 0),
            node(e + 1, 0, 0),
            node(e + 1, 1, 0),
            node(e, 1, 0),
            node(e, 0, 1),
            node(e + 1, 0, 1),
            node(e + 1, 1, 1),
            node(e, 1, 1),
        ];
        for a in 0..24 {
            for bb in 0..24 {
                k[(3 * nodes[a / 3] + a % 3, 3 * nodes[bb / 3] + bb % 3)] += ke[(a, bb)];
            }
        }
    }
    let mut f = DVector::<f64>::zeros(n);
    let fx = moment / h / 2.0; // two nodes on each face share the couple
    for j in 0..2 {
        f[3 * node(ne, j, 1)] += fx;
        f[3 * node(ne, j, 0)] -= fx;
    }
    // Clamp x = 0 (all dofs of its 4 nodes): keep the other dofs.
    let free: Vec<usize> = (0..n).filter(|&d| d / 3 % (ne + 1) != 0).collect();
    let kf = DMatrix::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
    let ff = DVector::from_fn(free.len(), |i, _| f[free[i]]);
    let u = kf.cholesky().unwrap().solve(&ff);
    let mut w = 0.0;
    for (idx, &d) in free.iter().enumerate() {
        if d % 3 == 2 && d / 3 % (ne + 1) == ne {
            w += u[idx] / 4.0;
        }
    }
    w.abs()
}

#[test]
fn pure_bending_matches_euler_bernoulli_where_the_plain_hex_locks() {
    let (l, b, h, m): (f64, f64, f64, f64) = (2.0, 0.1, 0.1, 1.0e3);
    let i = b * h.powi(3) / 12.0;
    let exact = m * l * l / (2.0 * 2.0e11 * i);
    let inc = tip_deflection(true, 10, l, b, h, m);
    let plain = tip_deflection(false, 10, l, b, h, m);
    eprintln!("tip deflection: exact {exact:e}, incompatible {inc:e}, plain {plain:e}");
    assert!(
        (inc - exact).abs() / exact < 1e-6,
        "incompatible {inc} vs {exact}"
    );
    assert!(
        plain < 0.5 * exact,
        "plain hex8 should lock: {plain} vs {exact}"
    );
}
