//! Universal files (UFF) and measured FRFs: files written by pyuff read to their known values
//! (`tests/data/uff/`, made by `scripts/pyuff_crosscheck.py generate`), FRFs through the
//! inverse FFT into the decay estimator at a known damping, with and without exponential
//! windows, and a dampscope-written file left for pyuff to check
//! (`scripts/pyuff_crosscheck.py check`).

use std::f64::consts::TAU;

use dampscope::decay::EvaluationRange;
use dampscope::source::frf::{
    measurement_from_uff, parse_frf_csv, FrfChannel, FrfSet, FrfToImpulse, ImpulseSet,
};
use dampscope::uff::{
    parse_uff, read_uff, write_function58, write_mode_shape55, write_nodes2411, Abscissa, AxisInfo,
    Function58, FunctionType, ModeShape55, Node, NodeDof, NodeValues, Ordinate, ShapeAnalysis,
    UffContents,
};
use realfft::num_complex::Complex;
use serde_json::Value;

use crate::common::{data, stft_estimate};

fn expected() -> Value {
    let text = std::fs::read_to_string(data("uff/pyuff_frf_expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// |a − b| ≤ rel·|b| (exact zeros must match exactly).
fn assert_rel(a: f64, b: f64, rel: f64, what: &str) {
    assert!((a - b).abs() <= rel * b.abs(), "{what}: {a} vs {b}");
}

fn pyuff_file() -> UffContents {
    read_uff(data("uff/pyuff_frf.uff")).unwrap()
}

#[test]
fn pyuff_frfs_time_response_nodes_units_and_shapes_read_to_1e_6() {
    let c = pyuff_file();
    let exp = expected();
    assert!(c.skipped.is_empty(), "{:?}", c.skipped);
    let u = c.units().unwrap();
    assert_eq!((u.code, u.length_factor), (5, 1000.0));
    // Nodes: 15 (1..3, mm) and 2411 (11..13).
    let nodes: Vec<_> = c.nodes().collect();
    assert_eq!(nodes.len(), 6);
    for (n, e) in nodes[..3].iter().zip(exp["nodes15"].as_array().unwrap()) {
        assert_eq!(n.label, e["label"].as_i64().unwrap());
        for (a, b) in n.xyz.iter().zip(floats(&e["xyz_mm"])) {
            assert_rel(*a, b, 1e-6, "node 15");
        }
    }
    for (n, e) in nodes[3..].iter().zip(exp["nodes2411"].as_array().unwrap()) {
        assert_eq!(n.label, e["label"].as_i64().unwrap());
        for (a, b) in n.xyz.iter().zip(floats(&e["xyz"])) {
            assert_rel(*a, b, 1e-15, "node 2411");
        }
    }
    // Three FRFs, complex double, 0…256 Hz by 1 Hz.
    let f: Vec<&Function58> = c.functions().collect();
    assert_eq!(f.len(), 4);
    for (g, e) in f[..3]
        .iter()
        .zip(exp["frf"]["channels"].as_array().unwrap())
    {
        assert_eq!(g.function_type, FunctionType::FrequencyResponse);
        assert_eq!(g.response.node, e["node"].as_i64().unwrap());
        assert_eq!(
            (
                g.response.direction,
                g.reference.node,
                g.reference.direction
            ),
            (3, 1, 3)
        );
        assert_eq!(
            g.abscissa,
            Abscissa::Even {
                start: 0.0,
                increment: 1.0
            }
        );
        assert!(g.double_precision);
        assert_eq!(g.abscissa_axis, AxisInfo::new(18, "Frequency", "Hz"));
        assert_eq!(g.ordinate_axis.units_label, "m/s^2");
        assert_eq!(g.denominator_axis.units_label, "N");
        let Ordinate::Complex(v) = &g.ordinate else {
            panic!("complex expected")
        };
        let (re, im) = (floats(&e["re"]), floats(&e["im"]));
        assert_eq!(v.len(), 257);
        for (k, z) in v.iter().enumerate() {
            assert_rel(
                z.re,
                re[k],
                1e-6,
                &format!("node {} re #{k}", g.response.node),
            );
            assert_rel(
                z.im,
                im[k],
                1e-6,
                &format!("node {} im #{k}", g.response.node),
            );
        }
    }
    // The time response.
    let t = f[3];
    assert_eq!(t.function_type, FunctionType::TimeResponse);
    let Ordinate::Real(y) = &t.ordinate else {
        panic!("real expected")
    };
    for (a, b) in y.iter().zip(floats(&exp["time"]["values"])) {
        assert_rel(*a, b, 1e-6, "time response");
    }
    // Mode shapes (55, single precision: E13.5).
    let m: Vec<&ModeShape55> = c.mode_shapes().collect();
    assert_eq!(m.len(), 2);
    let nm = &exp["normal_mode"];
    match m[0].analysis {
        ShapeAnalysis::NormalMode {
            mode,
            frequency_hz,
            modal_mass,
            viscous_damping_ratio,
            ..
        } => {
            assert_eq!(mode, 1);
            assert_eq!(
                (frequency_hz, modal_mass, viscous_damping_ratio),
                (55.0, 1.5, 0.02)
            );
        }
        ref other => panic!("{other:?}"),
    }
    let r: Vec<Vec<f64>> = nm["r"].as_array().unwrap().iter().map(floats).collect();
    for (k, node) in m[0].nodes.iter().enumerate() {
        for (d, z) in node.values.iter().enumerate() {
            assert_rel(z.re, r[d][k], 1e-6, "normal mode shape");
        }
    }
    let cm = &exp["complex_mode"];
    assert!(matches!(
        m[1].analysis,
        ShapeAnalysis::ComplexEigenvalue { mode: 2, .. }
    ));
    assert_rel(
        m[1].analysis.frequency_hz().unwrap(),
        120.5,
        1e-5,
        "complex mode f",
    );
    assert_rel(
        m[1].analysis.damping_ratio().unwrap(),
        0.01,
        1e-5,
        "complex mode ζ",
    );
    let (re, im): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (
        cm["re"].as_array().unwrap().iter().map(floats).collect(),
        cm["im"].as_array().unwrap().iter().map(floats).collect(),
    );
    for (k, node) in m[1].nodes.iter().enumerate() {
        for (d, z) in node.values.iter().enumerate() {
            assert_rel(z.re, re[d][k], 1e-6, "complex shape re");
            assert_rel(z.im, im[d][k], 1e-6, "complex shape im");
        }
    }
}

#[test]
fn pyuff_binary_58b_reads_to_full_precision() {
    let c = read_uff(data("uff/pyuff_58b.uff")).unwrap();
    let exp = expected();
    let f: Vec<&Function58> = c.functions().collect();
    assert_eq!(f.len(), 2);
    assert!(f.iter().all(|g| g.binary && g.double_precision));
    // Full double precision (serde_json parses the JSON's decimals to within an ulp).
    let Ordinate::Real(y) = &f[0].ordinate else {
        panic!()
    };
    let want = floats(&exp["time"]["values"]);
    assert_eq!(y.len(), want.len());
    for (a, b) in y.iter().zip(&want) {
        assert_rel(*a, *b, 1e-15, "58b time response");
    }
    // pyuff's header claims half the bytes of this complex FRF; record 7 decides.
    let Ordinate::Complex(v) = &f[1].ordinate else {
        panic!()
    };
    let e = &exp["frf"]["channels"][1];
    let (re, im) = (floats(&e["re"]), floats(&e["im"]));
    assert_eq!(v.len(), re.len());
    for (z, (a, b)) in v.iter().zip(re.iter().zip(&im)) {
        assert_rel(z.re, *a, 1e-15, "58b FRF re");
        assert_rel(z.im, *b, 1e-15, "58b FRF im");
    }
}

#[test]
fn pyuff_file_as_a_measurement_ids_sensors_in_metres_and_rates() {
    let m = measurement_from_uff(&pyuff_file(), "pyuff_frf.uff").unwrap();
    let frf = m.frf.unwrap();
    let ids: Vec<&str> = frf.channels.iter().map(|c| c.id.as_str()).collect();
    assert_eq!(ids, ["1", "2", "3"]);
    assert_eq!(frf.freq_hz.len(), 257);
    assert_eq!(frf.freq_hz[256], 256.0);
    assert_eq!(frf.channels[1].quantity.as_deref(), Some("acceleration"));
    assert_eq!(frf.channels[1].unit.as_deref(), Some("m/s^2/N"));
    assert_eq!(frf.exponential_window_tau_s, None);
    let imp = m.impulses.unwrap();
    assert_eq!(
        imp.sample_rate_hz, 1024.0,
        "1/9.76562e-4 snapped to whole Hz"
    );
    assert_eq!(imp.names, ["2"]);
    // Dataset 164 says mm: node 2 at (250, 125.5, 0) mm.
    let s2 = m.sensors.iter().find(|s| s.id == "2").unwrap();
    assert_eq!(
        (s2.x_m, s2.y_m, s2.z_m, s2.dir.as_str()),
        (0.25, 0.1255, Some(0.0), "z")
    );
    assert_eq!(m.sensors.len(), 4, "3 FRF channels and the time response");
    // The pyuff FRFs through the inverse FFT: fs = 2·fmax, 1/df long.
    let ir = frf.impulse_responses(&FrfToImpulse::default()).unwrap();
    assert_eq!(ir.sample_rate_hz, 512.0);
    assert_eq!(ir.channels[0].len(), 512);
}

/// Accelerance of one mode, −ω²/((jω − p)(jω − p̄)), pole p = −σ + jω_d (rad/s).
fn accelerance(freq_hz: &[f64], sigma: f64, wd: f64) -> Vec<Complex<f64>> {
    let p = Complex::new(-sigma, wd);
    freq_hz
        .iter()
        .map(|&f| {
            let jw = Complex::new(0.0, TAU * f);
            jw * jw / ((jw - p) * (jw - p.conj()))
        })
        .collect()
}

const FN_HZ: f64 = 55.0;
const ZETA: f64 = 0.02;

/// One mode at 55 Hz, ζ = 2 %, 0…1000 Hz by 0.1 Hz (10 s, fs 2 kHz); `extra_sigma` adds a
/// window's decay rate to the pole (what a test system's exponential window does to an FRF).
fn single_mode(extra_sigma: f64) -> FrfSet {
    let freq_hz: Vec<f64> = (0..=10_000).map(|k| k as f64 * 0.1).collect();
    let wn = TAU * FN_HZ;
    let h = accelerance(
        &freq_hz,
        ZETA * wn + extra_sigma,
        wn * (1.0 - ZETA * ZETA).sqrt(),
    );
    FrfSet {
        freq_hz,
        channels: vec![FrfChannel::new("s", h)],
        exponential_window_tau_s: None,
    }
}

/// (D, f_dominant) of the first channel in the 52.5–57.5 Hz band, 200 ms STFT, T30.
fn damping(ir: &ImpulseSet) -> (f64, f64) {
    let e = stft_estimate(
        &ir.channels[0],
        ir.sample_rate_hz,
        200.0,
        52.5,
        57.5,
        EvaluationRange::T30,
    );
    (
        e.damping_ratio_corrected.expect("a number"),
        e.f_dominant_hz.expect("a frequency"),
    )
}

#[test]
fn analytic_frf_gives_its_damping_and_windows_are_removed_within_1_percent() {
    let plain = single_mode(0.0)
        .impulse_responses(&FrfToImpulse::default())
        .unwrap();
    assert_eq!(plain.sample_rate_hz, 2000.0);
    let (d0, _) = damping(&plain);
    assert!((d0 / ZETA - 1.0).abs() < 0.01, "D = {d0}");
    assert!(
        plain.notes.iter().all(|n| !n.contains("wrap-around")),
        "{:?}",
        plain.notes
    );
    // An exponential window applied here: D grows by σ_win/(2πf); the correction removes it.
    let tau = 0.5;
    let opts = FrfToImpulse {
        exponential_window_tau_s: Some(tau),
        ..Default::default()
    };
    let w = single_mode(0.0).impulse_responses(&opts).unwrap();
    let (d, f) = damping(&w);
    let added = 1.0 / (tau * TAU * f);
    assert!(
        ((d - d0) / added - 1.0).abs() < 0.02,
        "raw {d}, plain {d0}, window adds {added}"
    );
    assert!(d > 1.25 * ZETA, "the window's damping is visible: {d}");
    let corrected = w.corrected_damping(d, f);
    assert!(
        (corrected / ZETA - 1.0).abs() < 0.01,
        "corrected D = {corrected}"
    );
}

#[test]
fn an_frf_the_test_system_windowed_is_corrected_from_uff_and_csv() {
    let tau = 0.25;
    let windowed = single_mode(1.0 / tau);
    // As a UFF whose ID line declares the window (dampscope's convention).
    let mut f = Function58::new(
        FunctionType::FrequencyResponse,
        NodeDof::new(7, 3),
        NodeDof::new(1, 3),
        Abscissa::Even {
            start: 0.0,
            increment: 0.1,
        },
        Ordinate::Complex(windowed.channels[0].values.clone()),
    );
    f.id_lines[4] = format!("exponential_window_tau_s={tau}");
    let mut bytes = Vec::new();
    write_function58(&mut bytes, &f).unwrap();
    let m = measurement_from_uff(&parse_uff(&bytes).unwrap(), "mem").unwrap();
    let set = m.frf.unwrap();
    assert_eq!(set.exponential_window_tau_s, Some(tau));
    let ir = set.impulse_responses(&FrfToImpulse::default()).unwrap();
    assert_eq!(ir.exponential_window_tau_s, Some(tau));
    assert!(
        ir.notes.iter().any(|n| n.contains("already windowed")),
        "{:?}",
        ir.notes
    );
    let (d, fd) = damping(&ir);
    assert!(d > ZETA + 0.8 / (tau * TAU * FN_HZ), "uncorrected D = {d}");
    let corrected = ir.corrected_damping(d, fd);
    assert!(
        (corrected / ZETA - 1.0).abs() < 0.01,
        "UFF: corrected D = {corrected}"
    );
    // As CSV (dB and degrees) with the window in a comment, starting at 10 Hz (zero padded).
    let mut csv = format!("# exponential_window_tau_s: {tau}\nfreq_hz,s_db,s_deg\n");
    for (f, z) in windowed
        .freq_hz
        .iter()
        .zip(&windowed.channels[0].values)
        .skip(100)
    {
        csv += &format!(
            "{f},{:.15e},{:.15e}\n",
            20.0 * z.norm().log10(),
            z.arg().to_degrees()
        );
    }
    let set = parse_frf_csv(&csv, "mem.csv").unwrap();
    let ir = set.impulse_responses(&FrfToImpulse::default()).unwrap();
    assert!(ir
        .notes
        .iter()
        .any(|n| n.contains("100 bins below f_min = 10 Hz")));
    let (d, fd) = damping(&ir);
    let corrected = ir.corrected_damping(d, fd);
    assert!(
        (corrected / ZETA - 1.0).abs() < 0.01,
        "CSV: corrected D = {corrected}"
    );
}

#[test]
fn the_taper_leaves_d_below_it_and_inside_it_within_1_percent() {
    // Below the taper: 55 Hz with the top 20 % (800–1000 Hz) tapered.
    let (d0, _) = damping(
        &single_mode(0.0)
            .impulse_responses(&FrfToImpulse::default())
            .unwrap(),
    );
    let opts = FrfToImpulse {
        taper_fraction: 0.2,
        ..Default::default()
    };
    let (d1, _) = damping(&single_mode(0.0).impulse_responses(&opts).unwrap());
    assert!((d1 / d0 - 1.0).abs() < 1e-3, "{d1} vs {d0}");
    // Inside it: 400 Hz, ζ = 0.2 %, 0…500 Hz, taper over the top 40 % (300–500 Hz), the mode
    // on its steepest part: W = 0.5 there, and it changes by 2.5 % across the mode's half-power
    // bandwidth.
    let freq_hz: Vec<f64> = (0..=2500).map(|k| k as f64 * 0.2).collect();
    let (f0, z0) = (400.0, 0.002);
    let wn = TAU * f0;
    let h = accelerance(&freq_hz, z0 * wn, wn * (1.0 - z0 * z0).sqrt());
    let set = FrfSet {
        freq_hz,
        channels: vec![FrfChannel::new("s", h)],
        exponential_window_tau_s: None,
    };
    let opts = FrfToImpulse {
        taper_fraction: 0.4,
        ..Default::default()
    };
    // The ringing after the first samples (the accelerance's direct term sits at t = 0).
    let ringing = |x: &[f64]| x[100..].iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut rms = Vec::new();
    for o in [FrfToImpulse::default(), opts] {
        let ir = set.impulse_responses(&o).unwrap();
        rms.push(ringing(&ir.channels[0]));
        let e = stft_estimate(
            &ir.channels[0],
            ir.sample_rate_hz,
            200.0,
            395.0,
            405.0,
            EvaluationRange::T30,
        );
        let d = e.damping_ratio_corrected.expect("a number");
        assert!(
            (d / z0 - 1.0).abs() < 0.01,
            "taper {}: D = {d}",
            o.taper_fraction
        );
    }
    // The taper did act: the mode's amplitude is halved.
    assert!((rms[1] / rms[0] - 0.5).abs() < 0.02, "{rms:?}");
}

#[test]
fn dampscope_writes_what_pyuff_reads() {
    // Written for `scripts/pyuff_crosscheck.py check` (its JSON beside it): FRFs, a time
    // response, a real and a complex mode (single precision, which pyuff reads) and nodes.
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("uff_format");
    std::fs::create_dir_all(&dir).unwrap();
    let freq: Vec<f64> = (0..=64).map(|k| k as f64 * 0.5).collect();
    let mut out = Vec::new();
    let mut functions = Vec::new();
    for (node, fn_hz) in [(1, 10.0), (2, 17.25)] {
        let h = accelerance(&freq, 0.03 * TAU * fn_hz, TAU * fn_hz);
        let mut f = Function58::new(
            FunctionType::FrequencyResponse,
            NodeDof::new(node, 3),
            NodeDof::new(1, 3),
            Abscissa::Even {
                start: 0.0,
                increment: 0.5,
            },
            Ordinate::Complex(h.clone()),
        );
        f.id_lines[0] = format!("dampscope FRF {node}+Z/1+Z");
        f.abscissa_axis = AxisInfo::new(18, "Frequency", "Hz");
        write_function58(&mut out, &f).unwrap();
        functions.push(
            serde_json::json!({"function_type": 4, "node": node, "direction": 3,
            "x": freq, "re": h.iter().map(|z| z.re).collect::<Vec<_>>(),
            "im": h.iter().map(|z| z.im).collect::<Vec<_>>()}),
        );
    }
    let fs = 256.0;
    let y: Vec<f64> = (0..300)
        .map(|i| (-(i as f64) / 40.0).exp() * (0.7 * i as f64).sin())
        .collect();
    let t = Function58::new(
        FunctionType::TimeResponse,
        NodeDof::new(2, 3),
        NodeDof::new(1, 3),
        Abscissa::Even {
            start: 0.0,
            increment: 1.0 / fs,
        },
        Ordinate::Real(y.clone()),
    );
    write_function58(&mut out, &t).unwrap();
    let x: Vec<f64> = (0..300).map(|i| i as f64 / fs).collect();
    functions
        .push(serde_json::json!({"function_type": 1, "node": 2, "direction": 3, "x": x, "re": y}));
    let values = |k: i64, complex: bool| -> Vec<Complex<f64>> {
        (0..3)
            .map(|d| {
                Complex::new(
                    0.1 * (k + d) as f64 - 0.15,
                    if complex { 0.05 * d as f64 } else { 0.0 },
                )
            })
            .collect()
    };
    let node_values = |complex| {
        (1..=3)
            .map(|k| NodeValues {
                node: k,
                values: values(k, complex),
            })
            .collect()
    };
    let shapes = [
        ModeShape55::normal_mode(1, 10.0, 0.03, node_values(false)),
        ModeShape55::complex_mode(2, 17.25, 0.03, node_values(true)),
    ];
    let mut shape_json = Vec::new();
    for s in &shapes {
        write_mode_shape55(&mut out, s).unwrap();
        let flat: Vec<Complex<f64>> = s.nodes.iter().flat_map(|n| n.values.clone()).collect();
        shape_json.push(serde_json::json!({"mode": if s.complex { 2 } else { 1 },
            "frequency_hz": s.analysis.frequency_hz().unwrap(),
            "re": flat.iter().map(|z| z.re).collect::<Vec<_>>(),
            "im": flat.iter().map(|z| z.im).collect::<Vec<_>>()}));
    }
    let nodes: Vec<Node> = (1..=3)
        .map(|k| Node::new(k, [0.1 * k as f64, 1.0 / (k as f64 + 2.0), -0.5]))
        .collect();
    write_nodes2411(&mut out, &nodes).unwrap();
    let node_json: Vec<_> = nodes
        .iter()
        .map(|n| serde_json::json!({"label": n.label, "xyz": n.xyz}))
        .collect();
    std::fs::write(dir.join("dampscope_written.uff"), &out).unwrap();
    let exp = serde_json::json!({"functions": functions, "shapes": shape_json, "nodes": node_json});
    std::fs::write(dir.join("dampscope_written.json"), exp.to_string()).unwrap();
    // And dampscope reads it back.
    let c = parse_uff(&out).unwrap();
    assert_eq!(
        (
            c.functions().count(),
            c.mode_shapes().count(),
            c.nodes().count()
        ),
        (3, 2, 3)
    );
}
