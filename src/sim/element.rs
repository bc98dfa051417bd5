//! The 8-node hexahedron with incompatible modes (Wilson–Taylor with Taylor's correction,
//! METHODS.md §5.2; the formulation of CalculiX C3D8I / Nastran CHEXA) and its consistent mass.
//!
//! The displacement is u = Σ N_a u_a + Σ_k P_k α_k with the bubbles P_k = 1 − ξ_k² and 9
//! internal dofs α. Two forms: [`hex8_incompatible_stiffness`] condenses α statically (24 dofs,
//! node a, component c → 3a + c, mass of the nodal part only); [`hex8_incompatible_internal`]
//! keeps α as 9 extra dofs with the bubbles' consistent mass, as CalculiX's C3D8I does (its
//! 2 × 2 × 2 Gauss mass is only semi-definite: each P_k is 2/3 at every Gauss point).
//! Strains in Voigt order xx, yy, zz, yz, xz, xy with engineering shears.
//! Plain trilinear hexahedra lock in bending; [`hex8_plain_stiffness`] is kept as a test oracle
//! of that locking.

use nalgebra::{SMatrix, SVector};

use super::error::SimError;

/// 24 × 24 element matrix.
pub type Mat24 = SMatrix<f64, 24, 24>;
type Mat6 = SMatrix<f64, 6, 6>;
type B24 = SMatrix<f64, 6, 24>;
type B9 = SMatrix<f64, 6, 9>;
type Mat3 = SMatrix<f64, 3, 3>;

/// Natural coordinates of the 8 corners in element order.
const CORNERS: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// Isotropic elasticity matrix C (Voigt xx, yy, zz, yz, xz, xy; engineering shear), Pa.
pub fn elasticity(youngs_modulus_pa: f64, poisson: f64) -> Mat6 {
    let (e, nu) = (youngs_modulus_pa, poisson);
    let lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    let mut c = Mat6::zeros();
    for i in 0..3 {
        for j in 0..3 {
            c[(i, j)] = lam;
        }
        c[(i, i)] += 2.0 * mu;
        c[(i + 3, i + 3)] = mu;
    }
    c
}

/// The 2 × 2 × 2 Gauss points (weights all 1).
fn gauss_points() -> [[f64; 3]; 8] {
    let g = 1.0 / 3f64.sqrt();
    let mut pts = [[0.0; 3]; 8];
    for (n, p) in pts.iter_mut().enumerate() {
        *p = [
            if n & 1 == 0 { -g } else { g },
            if n & 2 == 0 { -g } else { g },
            if n & 4 == 0 { -g } else { g },
        ];
    }
    pts
}

/// Shape functions N_a(ξ) and their natural derivatives (8 × 3, row a = ∂N_a/∂(ξ, η, ζ)).
fn shape(xi: [f64; 3]) -> ([f64; 8], SMatrix<f64, 8, 3>) {
    let mut n = [0.0; 8];
    let mut d = SMatrix::<f64, 8, 3>::zeros();
    for (a, c) in CORNERS.iter().enumerate() {
        let f = [1.0 + c[0] * xi[0], 1.0 + c[1] * xi[1], 1.0 + c[2] * xi[2]];
        n[a] = 0.125 * f[0] * f[1] * f[2];
        d[(a, 0)] = 0.125 * c[0] * f[1] * f[2];
        d[(a, 1)] = 0.125 * c[1] * f[0] * f[2];
        d[(a, 2)] = 0.125 * c[2] * f[0] * f[1];
    }
    (n, d)
}

/// Jacobian J_ij = ∂x_j/∂ξ_i at natural derivatives `dn`.
fn jacobian(coords: &[[f64; 3]; 8], dn: &SMatrix<f64, 8, 3>) -> Mat3 {
    let mut j = Mat3::zeros();
    for (a, x) in coords.iter().enumerate() {
        for i in 0..3 {
            for k in 0..3 {
                j[(i, k)] += dn[(a, i)] * x[k];
            }
        }
    }
    j
}

/// Strain–displacement rows of one node (or bubble) with Cartesian derivatives (dx, dy, dz),
/// written into columns `col..col + 3` of `b`.
fn put_b<const C: usize>(b: &mut SMatrix<f64, 6, C>, col: usize, d: [f64; 3]) {
    let [dx, dy, dz] = d;
    b[(0, col)] = dx;
    b[(1, col + 1)] = dy;
    b[(2, col + 2)] = dz;
    b[(3, col + 1)] = dz;
    b[(3, col + 2)] = dy;
    b[(4, col)] = dz;
    b[(4, col + 2)] = dx;
    b[(5, col)] = dy;
    b[(5, col + 1)] = dx;
}

/// Cartesian derivative rows: dN/dx = dN/dξ · J⁻ᵀ.
fn cartesian(dn_row: [f64; 3], jinv_t: &Mat3) -> [f64; 3] {
    let v = SVector::<f64, 3>::from(dn_row);
    let r = jinv_t.transpose() * v; // (dn_row · J⁻ᵀ)ᵀ = J⁻¹ dn_rowᵀ
    [r[0], r[1], r[2]]
}

struct Blocks {
    kuu: Mat24,
    kua: SMatrix<f64, 24, 9>,
    kaa: SMatrix<f64, 9, 9>,
}

fn blocks(coords: &[[f64; 3]; 8], c: &Mat6, element: usize) -> Result<Blocks, SimError> {
    let (_, dn0) = shape([0.0; 3]);
    let j0 = jacobian(coords, &dn0);
    let det0 = j0.determinant();
    let j0inv_t = j0
        .try_inverse()
        .filter(|_| det0 > 0.0)
        .ok_or_else(|| SimError::Element {
            element,
            message: format!("Jacobian at the centre must have det > 0, got {det0:e}"),
        })?
        .transpose();
    let mut out = Blocks {
        kuu: Mat24::zeros(),
        kua: SMatrix::zeros(),
        kaa: SMatrix::zeros(),
    };
    for xi in gauss_points() {
        let (_, dn) = shape(xi);
        let j = jacobian(coords, &dn);
        let det = j.determinant();
        let jinv_t = match j.try_inverse() {
            Some(inv) if det > 0.0 => inv.transpose(),
            _ => {
                return Err(SimError::Element {
                    element,
                    message: format!(
                        "Jacobian at Gauss point {xi:?} must have det > 0, got {det:e}"
                    ),
                })
            }
        };
        let mut b = B24::zeros();
        for a in 0..8 {
            let row = [dn[(a, 0)], dn[(a, 1)], dn[(a, 2)]];
            put_b(&mut b, 3 * a, cartesian(row, &jinv_t));
        }
        // Taylor's correction: bubble derivatives mapped with J₀ and scaled by det J₀/det J.
        let mut g = B9::zeros();
        for k in 0..3 {
            let mut row = [0.0; 3];
            row[k] = -2.0 * xi[k];
            let d = cartesian(row, &j0inv_t);
            let s = det0 / det;
            put_b(&mut g, 3 * k, [d[0] * s, d[1] * s, d[2] * s]);
        }
        let cb = c * b;
        let cg = c * g;
        out.kuu += b.transpose() * cb * det;
        out.kua += b.transpose() * cg * det;
        out.kaa += g.transpose() * cg * det;
    }
    Ok(out)
}

/// Condensed stiffness K_e = K_uu − K_uα K_αα⁻¹ K_αu of the incompatible-mode hexahedron with
/// corner coordinates `coords` (m, element order) and elasticity `c` (Pa); `element` names the
/// element in errors. N/m.
pub fn hex8_incompatible_stiffness(
    coords: &[[f64; 3]; 8],
    c: &Mat6,
    element: usize,
) -> Result<Mat24, SimError> {
    let b = blocks(coords, c, element)?;
    let chol = b.kaa.cholesky().ok_or_else(|| SimError::Element {
        element,
        message: "incompatible-mode block K_aa is not positive definite".into(),
    })?;
    let x = chol.solve(&b.kua.transpose());
    let mut k = b.kuu - b.kua * x;
    // Symmetrise the round-off.
    k = 0.5 * (k + k.transpose());
    Ok(k)
}

/// 33 × 33 element matrix: 24 nodal dofs then the 9 incompatible-mode amplitudes α.
pub type Mat33 = SMatrix<f64, 33, 33>;

/// The uncondensed incompatible-mode element, as in CalculiX's C3D8I (an 11-node element whose
/// 3 internal nodes carry α): stiffness [[K_uu, K_uα], [K_αu, K_αα]] and consistent mass
/// ∫ ρ N̂ᵀN̂ dV over the extended shape functions N̂ = (N_1..N_8, P_1, P_2, P_3), 2 × 2 × 2 Gauss.
/// Keeping α as dofs with mass is a Rayleigh–Ritz enlargement of the condensed element (static
/// condensation in dynamics is Guyan reduction), so its frequencies are lower. N/m and kg.
pub fn hex8_incompatible_internal(
    coords: &[[f64; 3]; 8],
    c: &Mat6,
    density: f64,
    element: usize,
) -> Result<(Mat33, Mat33), SimError> {
    let b = blocks(coords, c, element)?;
    let mut k = Mat33::zeros();
    k.fixed_view_mut::<24, 24>(0, 0).copy_from(&b.kuu);
    k.fixed_view_mut::<24, 9>(0, 24).copy_from(&b.kua);
    k.fixed_view_mut::<9, 24>(24, 0)
        .copy_from(&b.kua.transpose());
    k.fixed_view_mut::<9, 9>(24, 24).copy_from(&b.kaa);
    let mut m = Mat33::zeros();
    for xi in gauss_points() {
        let (n, dn) = shape(xi);
        let det = jacobian(coords, &dn).determinant();
        let mut ext = [0.0; 11];
        ext[..8].copy_from_slice(&n);
        for q in 0..3 {
            ext[8 + q] = 1.0 - xi[q] * xi[q];
        }
        for a in 0..11 {
            for bb in 0..11 {
                let v = density * ext[a] * ext[bb] * det;
                for comp in 0..3 {
                    m[(3 * a + comp, 3 * bb + comp)] += v;
                }
            }
        }
    }
    Ok((k, m))
}

/// The plain trilinear hexahedron's stiffness K_uu (locks in bending; a test oracle). N/m.
pub fn hex8_plain_stiffness(
    coords: &[[f64; 3]; 8],
    c: &Mat6,
    element: usize,
) -> Result<Mat24, SimError> {
    Ok(blocks(coords, c, element)?.kuu)
}

/// The incompatible modes' amplitudes α = −K_αα⁻¹ K_αu u_e for nodal displacements `u` (used
/// by the patch test: a linear displacement field must give α = 0).
pub fn incompatible_amplitudes(
    coords: &[[f64; 3]; 8],
    c: &Mat6,
    u: &SVector<f64, 24>,
) -> Result<SVector<f64, 9>, SimError> {
    let b = blocks(coords, c, 0)?;
    let chol = b.kaa.cholesky().ok_or_else(|| SimError::Element {
        element: 0,
        message: "incompatible-mode block K_aa is not positive definite".into(),
    })?;
    Ok(-chol.solve(&(b.kua.transpose() * u)))
}

/// Consistent mass M_e = ∫ ρ NᵀN dV (compatible part only; 2 × 2 × 2 Gauss, exact for boxes),
/// kg. `density` in kg/m³.
pub fn hex8_mass(coords: &[[f64; 3]; 8], density: f64) -> Mat24 {
    let mut m = Mat24::zeros();
    for xi in gauss_points() {
        let (n, dn) = shape(xi);
        let det = jacobian(coords, &dn).determinant();
        for a in 0..8 {
            for b in 0..8 {
                let v = density * n[a] * n[b] * det;
                for c in 0..3 {
                    m[(3 * a + c, 3 * b + c)] += v;
                }
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box(dx: f64, dy: f64, dz: f64) -> [[f64; 3]; 8] {
        let mut c = [[0.0; 3]; 8];
        for (a, p) in CORNERS.iter().enumerate() {
            c[a] = [
                0.5 * (p[0] + 1.0) * dx,
                0.5 * (p[1] + 1.0) * dy,
                0.5 * (p[2] + 1.0) * dz,
            ];
        }
        c
    }

    fn distorted() -> [[f64; 3]; 8] {
        let mut c = unit_box(1.0, 0.8, 0.6);
        let shifts = [
            [0.05, -0.03, 0.02],
            [0.12, 0.04, -0.05],
            [-0.08, 0.1, 0.03],
            [0.02, -0.07, 0.06],
            [-0.04, 0.05, -0.03],
            [0.1, -0.02, 0.04],
            [0.06, 0.09, -0.02],
            [-0.09, 0.03, 0.05],
        ];
        for (p, s) in c.iter_mut().zip(shifts) {
            for k in 0..3 {
                p[k] += s[k];
            }
        }
        c
    }

    #[test]
    fn rigid_body_modes_have_zero_energy_and_six_zero_eigenvalues() {
        let c = elasticity(7e10, 0.34);
        for coords in [unit_box(0.0625, 0.0625, 0.01), distorted()] {
            let k = hex8_incompatible_stiffness(&coords, &c, 0).unwrap();
            let ev = k.symmetric_eigenvalues();
            let max = ev.amax();
            let mut small: Vec<f64> = ev.iter().map(|v| v.abs() / max).collect();
            small.sort_by(|a, b| a.partial_cmp(b).unwrap());
            assert!(small[5] < 1e-10, "6 zero eigenvalues expected: {small:?}");
            assert!(
                small[6] > 1e-6,
                "only 6 zero eigenvalues expected: {small:?}"
            );
            // A rigid rotation about z explicitly.
            let mut u = SVector::<f64, 24>::zeros();
            for (a, p) in coords.iter().enumerate() {
                u[3 * a] = -p[1];
                u[3 * a + 1] = p[0];
            }
            assert!((k * u).norm() < 1e-8 * max * u.norm());
        }
    }

    #[test]
    fn patch_test_linear_field_gives_no_incompatible_modes() {
        // A linear field u = A x on a distorted element: Taylor's correction makes α = 0 and the
        // element forces equal those of the constant stress (∫ Bᵀ σ dV).
        let c = elasticity(2.0e11, 0.3);
        let coords = distorted();
        let a = [
            [1e-3, 2e-4, -3e-4],
            [5e-4, -2e-3, 1e-4],
            [-4e-4, 3e-4, 1.5e-3],
        ];
        let mut u = SVector::<f64, 24>::zeros();
        for (n, p) in coords.iter().enumerate() {
            for i in 0..3 {
                u[3 * n + i] = (0..3).map(|j| a[i][j] * p[j]).sum::<f64>();
            }
        }
        let alpha = incompatible_amplitudes(&coords, &c, &u).unwrap();
        assert!(alpha.norm() < 1e-12, "alpha = {alpha}");
        // Without the correction (bubble derivatives mapped with J(ξ)) α would not vanish:
        // checked indirectly by the condensed and plain K agreeing on the linear field.
        let kc = hex8_incompatible_stiffness(&coords, &c, 0).unwrap();
        let kp = hex8_plain_stiffness(&coords, &c, 0).unwrap();
        let (fc, fp) = (kc * u, kp * u);
        assert!((fc - fp).norm() < 1e-10 * fp.norm(), "{fc} vs {fp}");
    }

    #[test]
    fn mass_sums_to_rho_v() {
        let coords = distorted();
        let m = hex8_mass(&coords, 2700.0);
        // Σ over one direction's entries = ρ V; V by the Jacobian at the Gauss points.
        let mut sum = 0.0;
        for a in 0..8 {
            for b in 0..8 {
                sum += m[(3 * a, 3 * b)];
            }
        }
        let mut v = 0.0;
        for xi in gauss_points() {
            let (_, dn) = shape(xi);
            v += jacobian(&coords, &dn).determinant();
        }
        assert!((sum - 2700.0 * v).abs() < 1e-9 * sum);
        let bx = hex8_mass(&unit_box(0.5, 0.25, 0.02), 1000.0);
        let total: f64 = (0..24)
            .flat_map(|i| (0..24).map(move |j| (i, j)))
            .map(|(i, j)| bx[(i, j)])
            .sum();
        assert!((total - 3.0 * 1000.0 * 0.5 * 0.25 * 0.02).abs() < 1e-12);
    }

    #[test]
    fn inverted_element_is_a_typed_error() {
        let mut coords = unit_box(1.0, 1.0, 1.0);
        coords.swap(0, 6);
        let err = hex8_incompatible_stiffness(&coords, &elasticity(1e9, 0.3), 17).unwrap_err();
        assert!(err.to_string().starts_with("element 17"), "{err}");
    }
}
