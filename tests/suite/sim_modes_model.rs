//! Model file validation, mesh regions and sensor weights, and assembly invariants.

use dampscope::sim::assembly::{assemble, assemble_with, Formulation};
use dampscope::sim::eigen::{lowest_modes, reference_stiffness, sparse_matvec, ModeRequest};
use dampscope::sim::mesh::Mesh;
use dampscope::sim::model::{Model, REFERENCE_PLATE_TOML};
use dampscope::sim::SimError;

fn err_of(toml_text: &str) -> String {
    match Model::from_toml_str(toml_text) {
        Ok(_) => panic!("expected an error for:\n{toml_text}"),
        Err(e) => e.to_string(),
    }
}

fn small(nx: usize, ny: usize, nz: usize) -> Model {
    let mut m = Model::reference_plate();
    m.mesh.nx = nx;
    m.mesh.ny = ny;
    m.mesh.nz = nz;
    m.output.sensors = dampscope::sim::model::SensorSpec::Grid { nx: 2, ny: 2 };
    m
}

#[test]
fn impossible_values_name_their_key() {
    let r = REFERENCE_PLATE_TOML;
    assert_eq!(
        err_of(&r.replace("thickness = 0.02", "thickness = -0.02")),
        "plate.thickness: must be > 0, got -0.02"
    );
    assert!(err_of(&r.replace("poisson = 0.34", "poisson = 0.5"))
        .starts_with("material.poisson: must be in (-1, 0.5), got 0.5"));
    assert!(err_of(&r.replace("nz = 2", "nz = 0")).starts_with("mesh.nz:"));
    assert!(err_of(&r.replace("\"y1\"]", "\"z1\"]"))
        .starts_with("supports.pinned_edges[1]: unknown edge \"z1\""));
    assert!(err_of(&r.replace("x = 0.0625", "x = 2.5")).starts_with("excitation:"));
    let patch = format!("{r}\n[[patch]]\nx = [1.5, 2.5]\ny = [0.0, 1.0]\nloss_factor = 0.1\n");
    assert!(
        err_of(&patch).starts_with("patch[0].x: must lie inside the plate"),
        "{}",
        err_of(&patch)
    );
    let unknown = r.replace("[plate]", "[plate]\ncolour = \"red\"");
    let e = err_of(&unknown);
    assert!(e.contains("colour"), "{e}");
    let sls = format!("{r}\n[[patch]]\nx = [0.5, 1.0]\ny = [0.5, 1.0]\nsls = {{ e = 1e6, e_inf = -1.0, eta = 1.0 }}\n");
    assert!(
        err_of(&sls).starts_with("patch[0].sls.e_inf: must be > 0"),
        "{}",
        err_of(&sls)
    );
    // Found by the contract probe: an unknown key in the law (a typo of `eta`) and a modulus
    // beside it were dropped without a word, and the patch simulated with other values.
    let typo = sls
        .replace("eta = 1.0", "eta = 1.0, tau = 0.1")
        .replace("-1.0", "1e6");
    let e = err_of(&typo);
    assert!(e.contains("tau"), "{e}");
    let both = sls
        .replace("-1.0", "1e6")
        .replace("sls = {", "youngs_modulus = 5e9\nsls = {");
    assert!(
        err_of(&both).starts_with("patch[0].youngs_modulus: an sls patch takes its modulus"),
        "{}",
        err_of(&both)
    );
}

#[test]
fn sensor_outside_the_plate_in_a_file_is_an_error() {
    let dir = crate::common::fresh_dir("sensors");
    std::fs::write(dir.join("sensors.csv"), "id,x,y\nA,0.5,0.5\nB,2.5,1.0\n").unwrap();
    let text = REFERENCE_PLATE_TOML.replace(
        "sensors = { nx = 33, ny = 49 }",
        "sensors = { file = \"sensors.csv\" }",
    );
    std::fs::write(dir.join("m.toml"), text).unwrap();
    let model = Model::load(&dir.join("m.toml")).unwrap();
    let err = model.sensor_positions().unwrap_err().to_string();
    assert!(
        err.starts_with("output.sensors.file row 2 (id B):"),
        "{err}"
    );
    let err = assemble(&model).unwrap_err();
    assert!(matches!(err, SimError::InvalidValue { .. }));
}

#[test]
fn reference_plate_mesh_and_sensor_weights() {
    let model = Model::reference_plate();
    let mesh = Mesh::new(&model);
    assert_eq!(mesh.n_nodes(), 4851);
    // Grid sensors sit on nodes: one weight of 1 (or none on a pinned edge).
    let system = assemble(&model).unwrap();
    assert_eq!(system.sensors.len(), 33 * 49);
    for s in &system.sensors {
        let on_pinned = s.y_m == 0.0 || s.y_m == 3.0;
        if on_pinned {
            assert!(s.weights.is_empty(), "{s:?}");
        } else {
            assert_eq!(s.weights.len(), 1, "{s:?}");
            assert!((s.weights[0].1 - 1.0).abs() < 1e-12);
        }
    }
    // Between nodes: bilinear weights (nz even), trilinear over two layers (nz odd).
    let w = mesh.midplane_weights(0.03125, 0.09375);
    assert_eq!(w.len(), 4);
    assert!(w.iter().all(|(_, v)| (v - 0.25).abs() < 1e-12));
    let odd = Mesh::new(&small(4, 6, 3));
    let w = odd.midplane_weights(0.25, 0.25);
    assert_eq!(w.len(), 8);
    assert!((w.iter().map(|(_, v)| v).sum::<f64>() - 1.0).abs() < 1e-12);
}

#[test]
fn example_patch_is_exact_on_the_reference_mesh() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate-damped-patch.toml");
    let model = Model::load(&path).unwrap();
    let mesh = Mesh::new(&model);
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
    assert_eq!(
        mesh.region_of_element.iter().filter(|&&r| r == 1).count(),
        8 * 10 * 2
    );
    let mut off = model.clone();
    off.patches[0].x = [1.1, 1.625];
    assert_eq!(Mesh::new(&off).warnings.len(), 1);
    let system = assemble(&model).unwrap();
    let names: Vec<_> = system
        .stiffness_terms
        .iter()
        .map(|t| t.name.as_str())
        .collect();
    assert_eq!(names, ["plate", "patch 0"]);
    assert_eq!(system.stiffness_terms[1].loss_factor, 0.10);
}

fn ones_x(system_n: usize, model: &Model, formulation: Formulation) -> Vec<f64> {
    // Rigid translation in x over the nodal dofs of a free plate (internal dofs 0).
    let mesh = Mesh::new(model);
    let n_nodal = 3 * mesh.n_nodes();
    let mut u = vec![0.0; system_n];
    for node in 0..mesh.n_nodes() {
        u[3 * node] = 1.0;
    }
    assert!(formulation == Formulation::Condensed || system_n > n_nodal);
    u
}

#[test]
fn total_mass_is_plate_plus_point_masses() {
    for formulation in [Formulation::InternalDofs, Formulation::Condensed] {
        let mut model = small(6, 8, 2);
        model.supports.pinned_edges.clear();
        let text = "[[point_mass]]\nx = 0.3\ny = 1.1\nmass = 2.5\n";
        let extra: Model =
            Model::from_toml_str(&format!("{REFERENCE_PLATE_TOML}\n{text}")).unwrap();
        model.point_masses = extra.point_masses;
        let system = assemble_with(&model, formulation).unwrap();
        let u = ones_x(system.n_free, &model, formulation);
        let mut mu = vec![0.0; system.n_free];
        sparse_matvec(&system.mass, &u, &mut mu);
        let total: f64 = u.iter().zip(&mu).map(|(a, b)| a * b).sum();
        let expected = 2700.0 * 2.0 * 3.0 * 0.02 + 2.5;
        assert!(
            (total - expected).abs() < 1e-9 * expected,
            "{total} vs {expected}"
        );
    }
}

#[test]
fn stiffness_is_symmetric_and_a_free_plate_has_six_rigid_modes() {
    let mut model = small(6, 8, 2);
    model.supports.pinned_edges.clear();
    let system = assemble(&model).unwrap();
    let k0 = reference_stiffness(&system).unwrap();
    let n = system.n_free;
    let x: Vec<f64> = (0..n)
        .map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.5)
        .collect();
    let y: Vec<f64> = (0..n)
        .map(|i| ((i * 104729) % 97) as f64 / 97.0 - 0.5)
        .collect();
    let (mut kx, mut ky) = (vec![0.0; n], vec![0.0; n]);
    sparse_matvec(&k0, &x, &mut kx);
    sparse_matvec(&k0, &y, &mut ky);
    let a: f64 = y.iter().zip(&kx).map(|(p, q)| p * q).sum();
    let b: f64 = x.iter().zip(&ky).map(|(p, q)| p * q).sum();
    assert!((a - b).abs() < 1e-12 * a.abs().max(b.abs()), "{a} vs {b}");
    let modes = lowest_modes(&system, ModeRequest::Count(8)).unwrap();
    let f = &modes.frequencies_hz;
    assert!(f[..6].iter().all(|&v| v < 1e-2), "{f:?}");
    assert!(f[6] > 1.0, "{f:?}");
}

#[test]
fn sparse_eigen_solver_agrees_with_a_dense_oracle() {
    for formulation in [Formulation::InternalDofs, Formulation::Condensed] {
        let model = small(4, 6, 1);
        let system = assemble_with(&model, formulation).unwrap();
        let n = system.n_free;
        let k0 = reference_stiffness(&system).unwrap();
        let dense = |a: &faer::sparse::SparseColMat<usize, f64>| {
            let mut d = nalgebra::DMatrix::<f64>::zeros(n, n);
            let mut e = vec![0.0; n];
            let mut col = vec![0.0; n];
            for j in 0..n {
                e[j] = 1.0;
                sparse_matvec(a, &e, &mut col);
                e[j] = 0.0;
                for i in 0..n {
                    d[(i, j)] = col[i];
                }
            }
            d
        };
        let (k, m) = (dense(&k0), dense(&system.mass));
        // M is only semi-definite with internal dofs (the bubbles are 2/3 at every Gauss
        // point), so the oracle solves the inverted problem: with A = K0 − σM = L Lᵀ (σ < 0),
        // L⁻¹ M L⁻ᵀ z = θ z and λ = σ + 1/θ.
        let sigma = -1.0e3;
        let l = (&k - sigma * &m).cholesky().unwrap().l();
        let c = l.solve_lower_triangular(&m).unwrap();
        let c = l.solve_lower_triangular(&c.transpose()).unwrap();
        let c = 0.5 * (&c + c.transpose());
        let mut theta: Vec<f64> = c.symmetric_eigenvalues().iter().copied().collect();
        theta.sort_by(|a, b| b.total_cmp(a));
        let oracle: Vec<f64> = theta
            .iter()
            .take(15)
            .map(|t| (sigma + 1.0 / t).max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect();
        let modes = lowest_modes(&system, ModeRequest::Count(15)).unwrap();
        for (i, (a, b)) in modes.frequencies_hz.iter().zip(&oracle).enumerate() {
            assert!(
                (a - b).abs() < 1e-8 * b,
                "{formulation:?} mode {}: {a} vs dense {b}",
                i + 1
            );
        }
    }
}

#[test]
fn edge_springs_integrate_to_k_times_length_and_stiff_springs_act_like_pins() {
    for nz in [2, 3] {
        let mut model = small(8, 12, nz);
        model.supports.pinned_edges.clear();
        let extra = Model::from_toml_str(&format!(
            "{REFERENCE_PLATE_TOML}\n[[edge_spring]]\nedge = \"y0\"\nstiffness_per_length = 1.0e13\n\
             [[edge_spring]]\nedge = \"x1\"\nstiffness_per_length = 2.0e3\n"
        ))
        .unwrap();
        model.edge_springs = extra.edge_springs;
        let system = assemble(&model).unwrap();
        let n = system.n_free;
        let mesh = Mesh::new(&model);
        // A uniform uz = 1 stretches every spring by 1: energy k · L per edge.
        let mut u = vec![0.0; n];
        for node in 0..mesh.n_nodes() {
            u[3 * node + 2] = 1.0;
        }
        for (term, expected) in system.stiffness_terms[1..]
            .iter()
            .zip([1.0e13 * 2.0, 2.0e3 * 3.0])
        {
            let mut ku = vec![0.0; n];
            sparse_matvec(&term.matrix, &u, &mut ku);
            let e: f64 = u.iter().zip(&ku).map(|(a, b)| a * b).sum();
            assert!(
                (e - expected).abs() < 1e-9 * expected,
                "{}: {e} vs {expected}",
                term.name
            );
            assert_eq!(term.loss_factor, 0.0);
        }
    }
    // Very stiff z springs on both 2 m edges ≈ the pinned plate (after 3 in-plane rigid modes).
    let pinned = assemble(&small(8, 12, 2)).unwrap();
    let fp = lowest_modes(&pinned, ModeRequest::Count(5))
        .unwrap()
        .frequencies_hz;
    let mut sprung = small(8, 12, 2);
    sprung.supports.pinned_edges.clear();
    sprung.edge_springs = Model::from_toml_str(&format!(
        "{REFERENCE_PLATE_TOML}\n[[edge_spring]]\nedge = \"y0\"\nstiffness_per_length = 1.0e14\n\
         [[edge_spring]]\nedge = \"y1\"\nstiffness_per_length = 1.0e14\n"
    ))
    .unwrap()
    .edge_springs;
    let fs = lowest_modes(&assemble(&sprung).unwrap(), ModeRequest::Count(8))
        .unwrap()
        .frequencies_hz;
    assert!(fs[..3].iter().all(|&f| f < 0.01), "{fs:?}");
    for (a, b) in fs[3..].iter().zip(&fp) {
        assert!((a - b).abs() / b < 0.005, "sprung {a} vs pinned {b}");
    }
}

#[test]
fn every_example_model_loads_and_assembles() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let model = Model::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assemble(&model).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        n += 1;
    }
    assert!(n >= 4, "{n} example models");
}

/// Found with a hand-written model of nz = 1 (valid: FORMATS.md §3 sets no parity): the pinned
/// edges fixed ux = uy on the lower node layer, a pin on the bottom face rather than the
/// mid-plane line, which restrained the section's rotation: the first mode of the reference
/// plate pinned on y0 and y1 came out 60 % high with nz = 1 and 12 % with nz = 3. Every nz now
/// gives the same plate.
#[test]
fn odd_layer_counts_pin_the_mid_plane_like_even_ones() {
    let freqs = |nz: usize| {
        let system = assemble(&small(8, 12, nz)).unwrap();
        lowest_modes(&system, ModeRequest::Count(4))
            .unwrap()
            .frequencies_hz
    };
    let even = freqs(2);
    for nz in [1, 3] {
        for (k, (a, b)) in freqs(nz).iter().zip(&even).enumerate() {
            assert!(
                (a / b - 1.0).abs() < 0.005,
                "nz {nz} mode {}: {a} vs {b}",
                k + 1
            );
        }
    }
}

/// Found with a hand-written 1 mm sheet on an 8 × 12 mesh: its second mode came out 88 % high
/// without a word (flat C3D8I elements stiffen; CalculiX's element alike). A mesh whose elements
/// are much wider than the plate is thick now says so; the report's reference mesh does not.
#[test]
fn elements_much_wider_than_the_plate_is_thick_are_warned_about() {
    let flat = |m: &Model| Mesh::new(m).warnings.iter().any(|w| w.contains("stiffen"));
    assert!(
        !flat(&Model::reference_plate()),
        "62.5 mm elements on 20 mm"
    );
    assert!(flat(&small(8, 12, 2)), "250 mm elements on 20 mm");
    assert!(flat(&small(8, 12, 1)), "the same with one layer");
}

/// Found with hand-written models: `output.sensors` of `{ nx = 3 }`, `{ nx = 3.0, ny = 3 }` or
/// `{ files = … }` all answered "data did not match any variant of untagged enum SensorSpec",
/// and `{ nx, ny, file }` was taken as a grid with the file ignored. Each now says what is
/// expected and what was given.
#[test]
fn sensor_specs_that_are_neither_grid_nor_file_say_why() {
    let r = REFERENCE_PLATE_TOML;
    let line = r
        .lines()
        .find(|l| l.trim_start().starts_with("sensors ="))
        .expect("the reference plate gives its sensors");
    let with = |spec: &str| r.replace(line, &format!("sensors = {spec}"));
    let half = err_of(&with("{ nx = 3 }"));
    assert!(
        half.contains("expected either { nx = N, ny = N }") && half.contains("got nx = 3"),
        "{half}"
    );
    let both = err_of(&with("{ nx = 3, ny = 3, file = \"s.csv\" }"));
    assert!(both.contains("file = \"s.csv\""), "{both}");
    let typo = err_of(&with("{ files = \"s.csv\" }"));
    assert!(typo.contains("unknown field `files`"), "{typo}");
    assert!(!err_of(&with("{ nx = 3.0, ny = 3 }")).contains("untagged"));
}

/// Found by the contract probe: a mesh far too coarse for the frequencies asked (a 16 × 24 mesh
/// of the reference plate to 1 kHz: 3.6 elements per bending wavelength) gave modes several %
/// high without a word. `modes` now warns about the highest mode it found, `simulate` and
/// `diagnose` about the range they cover; the reference model to its 2 kHz does not warn.
#[test]
fn modes_beyond_what_the_mesh_resolves_are_warned_about() {
    let dir = crate::common::fresh_dir("coarse-modes");
    let coarse = REFERENCE_PLATE_TOML
        .replace("nx = 32", "nx = 16")
        .replace("ny = 48", "ny = 24");
    let path = dir.join("coarse.toml");
    std::fs::write(&path, coarse).unwrap();
    let o = crate::common::run_dampscope(
        &["modes", "--model", path.to_str().unwrap(), "--fmax", "1000"],
        b"",
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("elements per bending wavelength at 978 Hz"),
        "{e}"
    );
    let o = crate::common::run_dampscope(&["modes", "--count", "3"], b"");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!e.contains("wavelength"), "{e}");
    let reference = Model::reference_plate();
    assert_eq!(
        dampscope::sim::resolution::model_warnings(&reference, reference.output.fmax),
        Vec::<String>::new()
    );
}
