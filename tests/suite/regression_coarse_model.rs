//! Found probing `diagnose` with a coarse model of a small plate (1 × 1.5 × 0.02 m aluminium on
//! 12 × 18 × 2, pinned on y0 and y1) against recordings of the same plate on a finer mesh
//! (36 × 54 × 2), 88 sensors between the nodes, noise 50 dB under the mean signal power, 3 s
//! records, modes to 400 Hz. The right model was given a false stiffer region or point mass in
//! six of six recordings: its discretisation pattern came from a 6 × 9 mesh (3.7 elements per
//! bending wavelength at the view's top), which no longer errs as h² and explained almost
//! nothing of the mismatch (0.43 → 0.40 % RMS). A coarse model's pattern now comes from the
//! mesh twice as fine (0.07 % left). With it, a concealed mass was also no longer rejected as
//! "fits worse" because the updated model paired a close triple of modes the model as given
//! had not: the fit is compared on the modes paired before and after.

use std::path::{Path, PathBuf};

use dampscope::diagnose::procedure::{diagnose, DiagnoseSettings, MIN_BIC_GAIN};
use dampscope::diagnose::report::Diagnosis;
use dampscope::sim::model::Model;

use crate::common::{self, fresh_dir, ScratchDir, TestCommand};

/// The plate; `{plate}`, `{mesh}` and `{sensors}` are filled in, a point mass may be appended.
const PLATE: &str = r#"
[plate]
{plate}
[mesh]
{mesh}
nz = 2
[material]
youngs_modulus = 7.0e10
poisson = 0.34
density = 2700.0
loss_factor = 0.05
[supports]
pinned_edges = ["y0", "y1"]
[excitation]
x = 0.07
y = 0.09
dir = "z"
force = 1.0
[output]
fmax = 500.0
df = 0.3333333333333333
{sensors}
"#;

/// Modes compared up to here, Hz (12 modes of the plate).
const FMAX_HZ: f64 = 400.0;

/// The small plate of the first two tests: lx, ly, thickness in m.
const SMALL: (f64, f64, f64) = (1.0, 1.5, 0.02);

/// 8 × 11 sensors on a grid offset from every mesh's nodes of a `lx` × `ly` plate.
fn sensor_file(dir: &Path, (lx, ly): (f64, f64)) -> PathBuf {
    let mut csv = String::from("id,x,y,dir\n");
    for j in 0..11 {
        for i in 0..8 {
            let x = 0.05 + (lx - 0.1) * (i as f64 + 0.37) / 8.0;
            let y = 0.05 + (ly - 0.1) * (j as f64 + 0.41) / 11.0;
            csv += &format!("s{:03},{x:.4},{y:.4},z\n", 8 * j + i);
        }
    }
    let path = dir.join("sensors.csv");
    std::fs::write(&path, csv).unwrap();
    path
}

/// The TOML of plate `(lx, ly, thickness)` on an `nx` × `ny` mesh, with `extra` appended.
fn plate(
    (lx, ly, h): (f64, f64, f64),
    (nx, ny): (usize, usize),
    sensors: &str,
    extra: &str,
) -> String {
    PLATE
        .replace("{plate}", &format!("lx = {lx}\nly = {ly}\nthickness = {h}"))
        .replace("{mesh}", &format!("nx = {nx}\nny = {ny}"))
        .replace("{sensors}", sensors)
        + extra
}

/// The truth's TOML (plate `dims` on `mesh` with `extra`, at the off-node sensors) in a fresh
/// directory `name`, and the model: the same plate on `coarse` without `extra`.
fn truth_and_model(
    name: &str,
    dims: (f64, f64, f64),
    (mesh, coarse): ((usize, usize), (usize, usize)),
    extra: &str,
) -> (ScratchDir, PathBuf, PathBuf) {
    let dir = fresh_dir(name);
    let sensors = sensor_file(&dir, (dims.0, dims.1));
    let file = format!("sensors = {{ file = \"{}\" }}", sensors.display());
    let (truth, model) = (dir.join("truth.toml"), dir.join("model.toml"));
    std::fs::write(&truth, plate(dims, mesh, &file, extra)).unwrap();
    let grid = "sensors = { nx = 9, ny = 13 }";
    std::fs::write(&model, plate(dims, coarse, grid, "")).unwrap();
    (dir, truth, model)
}

/// Recordings of the small plate on 36 × 54 with `extra` (noise-free; noise is added per seed),
/// and the 12 × 18 model without it.
fn recordings(name: &str, extra: &str) -> (PathBuf, Model, ScratchDir) {
    let (dir, truth, model) = truth_and_model(name, SMALL, ((36, 54), (12, 18)), extra);
    let set = dir.join("set");
    common::simulate_set(&truth, &set, &[]);
    (set, Model::load(&model).expect("the coarse model"), dir)
}

/// `dampscope diagnose SET --model MODEL --out OUT --fmax FMAX_HZ`, which must succeed: its
/// standard output and `diagnosis.json`.
fn diagnose_cli(
    set: &Path,
    model: &Path,
    out: &Path,
    fmax_hz: &str,
) -> (String, serde_json::Value) {
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let (set, model, out_dir) = (path(set), path(model), path(out));
    let stdout = TestCommand::new([
        "diagnose", &set, "--model", &model, "--out", &out_dir, "--fmax", fmax_hz,
    ])
    .ok();
    let text = std::fs::read_to_string(out.join("diagnosis.json")).unwrap();
    (stdout, serde_json::from_str(&text).unwrap())
}

/// Recordings of plate `dims` on `meshes.0` with `extra`, simulated with noise 50 dB under the
/// mean signal power (`seed`), diagnosed by the CLI against the plate on `meshes.1` to
/// `fmax_hz`: the directory, the standard output and `diagnosis.json`.
fn diagnose_noisy(
    name: &str,
    dims: (f64, f64, f64),
    meshes: ((usize, usize), (usize, usize)),
    extra: &str,
    seed: u64,
    fmax_hz: &str,
) -> (ScratchDir, String, serde_json::Value) {
    let (dir, truth, model) = truth_and_model(name, dims, meshes, extra);
    let (set, out) = (dir.join("set"), dir.join("out"));
    let seed = seed.to_string();
    let noise = [
        "--snr-db",
        "50",
        "--snr-definition",
        "mean-power",
        "--seed",
        &seed,
    ];
    common::simulate_set(&truth, &set, &noise);
    let (stdout, json) = diagnose_cli(&set, &model, &out, fmax_hz);
    (dir, stdout, json)
}

/// Distance from `found` to the nearest of `truth` and its mirror images on the small plate, m.
fn offset_on_small_plate_m(found: (f64, f64), (tx, ty): (f64, f64)) -> f64 {
    let (lx, ly, _) = SMALL;
    [(tx, ty), (lx - tx, ty), (tx, ly - ty), (lx - tx, ly - ty)]
        .iter()
        .map(|(x, y)| (found.0 - x).hypot(found.1 - y))
        .fold(f64::INFINITY, f64::min)
}

/// A point mass of `mass_kg` at (`x_m`, `y_m`), as a model's TOML table.
fn point_mass_toml((x_m, y_m, mass_kg): (f64, f64, f64)) -> String {
    format!("[[point_mass]]\nx = {x_m}\ny = {y_m}\nmass = {mass_kg}\n")
}

/// The small plate on 36 × 54 with a point mass `truth` (x, y in m, mass in kg), recorded at
/// 50 dB on mean power (`seed`) and diagnosed by the CLI against the 12 × 18 model to 400 Hz:
/// the directory, the standard output and `diagnosis.json`.
fn diagnose_small_with_mass(
    name: &str,
    truth: (f64, f64, f64),
    seed: u64,
) -> (ScratchDir, String, serde_json::Value) {
    let meshes = ((36, 54), (12, 18));
    diagnose_noisy(name, SMALL, meshes, &point_mass_toml(truth), seed, "400")
}

/// The findings of `diagnosis.json` other than the noise floor.
fn physics_in(json: &serde_json::Value) -> Vec<&serde_json::Value> {
    let all = json["findings"].as_array().expect("a findings array");
    all.iter().filter(|f| f["kind"] != "noise_floor").collect()
}

/// `diagnosis.json` names one finding, an added mass within 0.1 m of `(x, y)` (or a mirror
/// image) and within 25 % of `mass_kg`.
fn assert_mass_alone_near(
    json: &serde_json::Value,
    stdout: &str,
    (x, y, mass_kg): (f64, f64, f64),
) {
    let physics = physics_in(json);
    assert_eq!(physics.len(), 1, "{physics:?}\n{stdout}");
    let found = physics[0];
    assert_eq!(found["kind"], "added_mass", "{found}");
    let (place, m) = place_and_mass(found);
    let off = offset_on_small_plate_m(place, (x, y));
    assert!(off < 0.1, "{off} m: {found}");
    assert!(common::rel_err(m, mass_kg) < 0.25, "{m} kg: {found}");
}

/// A finding's place (x, y) and mass from `diagnosis.json`.
fn place_and_mass(found: &serde_json::Value) -> ((f64, f64), f64) {
    let at = |k: &str| found["point"][k].as_f64().unwrap();
    (
        (at("x"), at("y")),
        found["parameters"]["mass_kg"].as_f64().unwrap(),
    )
}

/// `diagnose` of `set` at 50 dB on mean power (`seed`) against `model`.
fn diagnose_at(set: &Path, model: &Model, seed: u64) -> Diagnosis {
    let (rec, sensors) = common::noisy_set(set.to_str().unwrap(), 50.0, seed);
    let settings = DiagnoseSettings {
        fmax_hz: FMAX_HZ,
        ..DiagnoseSettings::default()
    };
    diagnose(&rec, &sensors, model, &settings).expect("a diagnosis")
}

/// `diagnose` of `set` against `model` names no physics, for each noise seed of `seeds`.
fn assert_no_physics(set: &Path, model: &Model, seeds: &[u64]) {
    for &seed in seeds {
        let d = diagnose_at(set, model, seed);
        assert!(
            common::physics(&d).is_empty(),
            "seed {seed}: {:?}",
            d.findings
        );
    }
}

/// The right model, coarser than the recordings: no physics, for two noise seeds.
#[test]
fn a_coarse_right_model_gets_no_finding() {
    let (set, model, dir) = recordings("coarse-control", "");
    assert_no_physics(&set, &model, &[1, 2]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A 2.87 kg mass on the 81 kg plate (drawn at random in the probe): found alone, at the true
/// point or one of its mirror images within 0.1 m, weighed within 30 % (2.73 kg measured).
/// Before the fix: 3.50 kg and a false stiffer region beside it.
#[test]
fn a_mass_on_a_coarse_model_is_found_alone() {
    let (tx, ty, tm) = (0.869, 0.797, 2.87);
    let mass = point_mass_toml((tx, ty, tm));
    let (set, model, dir) = recordings("coarse-mass", &mass);
    let d = diagnose_at(&set, &model, 12);
    let physics = common::physics(&d);
    assert_eq!(physics.len(), 1, "{:?}", d.findings);
    let f = physics[0];
    assert_eq!(f.kind, "added_mass", "{f:?}");
    let p = f.point.as_ref().expect("a point");
    let off = offset_on_small_plate_m((p.x, p.y), (tx, ty));
    assert!(off < 0.1, "{off} m: {f:?}");
    let m = f.parameters["mass_kg"];
    assert!(common::rel_err(m, tm) < 0.3, "{m} kg");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A thin plate (1.5 × 2 × 0.01 m) on 16 × 22 (its elements 9.4 times as wide as the plate is
/// thick: the model's frequencies 4.9 % high in the median, scatter 4.6 %) against 48 × 66
/// recordings at 50 dB (simulated with their noise, seed 1), modes to 200 Hz. The first-order
/// scan's best, a point mass at the free edge (BIC gain 7.3), came to 0 kg when refitted
/// through the re-solved model, and was returned as a finding of "0.00 kg". A size that comes
/// to no change is now rejected, and the verdict says so.
/// The thin plate of the probes: 1.5 × 2 × 0.01 m, recorded on 48 × 66, modelled on 16 × 22.
const THIN_DIMS_M: (f64, f64, f64) = (1.5, 2.0, 0.01);
/// See [`THIN_DIMS_M`]: (recording mesh, model mesh).
const THIN_MESHES: ((usize, usize), (usize, usize)) = ((48, 66), (16, 22));

#[test]
fn a_size_refitted_to_nothing_is_no_finding() {
    let (dir, stdout, json) = diagnose_noisy("coarse-thin", THIN_DIMS_M, THIN_MESHES, "", 1, "200");
    let physics = physics_in(&json);
    assert!(physics.is_empty(), "{physics:?}\n{stdout}");
    assert!(
        stdout.contains("added_mass, was rejected because refitted through the re-solved model"),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The thin plate of the test above with a 1.83 kg mass at (0.902, 0.22) m (the probe's seed 9,
/// case 3; noise seed 4). Once masses were placed between grid points, a mass was found first
/// and a stiffer region beside it; weighed again beside the region the mass came to nothing and
/// was dropped, and the region was left as the only finding (x 0.84–1.50 m, +23 %; FRF error
/// 0.50 → 0.85), though alone it had scored −7.9 against "no change". Through its re-solved
/// model the mass itself does not beat "no change" by 6, and is now rejected before the region
/// is looked for. Asserted: no stiffer region, and the report says why.
#[test]
fn a_thin_plate_mass_leaves_no_false_region_behind() {
    let mass = point_mass_toml((0.902, 0.22, 1.83));
    let (dir, stdout, json) = diagnose_noisy(
        "coarse-thin-alone",
        THIN_DIMS_M,
        THIN_MESHES,
        &mass,
        4,
        "200",
    );
    let physics = physics_in(&json);
    let kinds: Vec<&str> = physics.iter().filter_map(|f| f["kind"].as_str()).collect();
    assert!(!kinds.contains(&"stiffness_change"), "{kinds:?}\n{stdout}");
    let report = std::fs::read_to_string(dir.join("out").join("report.md")).unwrap();
    // Its row gives the gain through the re-solved model: below the bar that rejected it.
    let gain = rejected_row_gain(
        &report,
        "added_mass (rejected: not borne out once re-solved)",
    );
    assert!(gain < MIN_BIC_GAIN, "{gain}: {report}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The BIC gain in the report's score table on the row whose kind is `kind`.
fn rejected_row_gain(report: &str, kind: &str) -> f64 {
    let row = report
        .lines()
        .find(|l| l.contains(&format!("| {kind} |")))
        .unwrap_or_else(|| panic!("no row {kind}: {report}"));
    row.trim_end_matches(" |")
        .rsplit("| ")
        .next()
        .and_then(|g| g.parse().ok())
        .unwrap_or_else(|| panic!("no gain in {row}"))
}

/// Found with the same probe (`scripts/coarse_model_probe.py … 5 12`, case 5): a 1.26 kg mass
/// 0.17 m from a pinned edge, recorded with its noise (seed 6), was placed at the edge,
/// (0.53, 0.03) m, and weighed 38.4 kg: near the edge φ² grows from zero, so a heavy mass there
/// and a light one further in move the modes alike. The places whose first-order fit ties with
/// the best now go to the shape test with the mirror images: 2.20 kg at (0.47, 0.12) m. Still
/// +75 % (README, known limits); asserted: the place within 0.15 m and the size within a
/// factor of 2.5, which the edge's 38 kg fails.
#[test]
fn a_mass_near_a_pinned_edge_is_not_moved_onto_it() {
    let (tx, ty, tm) = (0.559, 0.166, 1.26);
    let (dir, _, json) = diagnose_small_with_mass("coarse-edge", (tx, ty, tm), 6);
    let found = json["findings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["kind"] == "added_mass")
        .unwrap_or_else(|| panic!("no mass: {}", json["findings"]));
    let ((x, y), m) = place_and_mass(found);
    let off = offset_on_small_plate_m((x, y), (tx, ty));
    assert!(off < 0.15 && m < 2.5 * tm, "{m} kg at ({x}, {y}): {found}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Found with the same probe (seed 6, case 3: a 3.31 kg mass at (0.716, 0.477) m, recorded with
/// its noise, seed 4): the coarse grid's nearest point lay 0.05 m off, where φ² of the modes
/// that bend there differs enough that the mass was weighed 4.71 kg (+42 %) and a stiffer
/// region was named beside it. A found mass is now placed between the grid's points (the fine
/// place kept when the re-solved model scores better by 2): 3.95 kg, alone. Asserted: one
/// finding, within 0.1 m of the mass or a mirror image, within 25 %.
#[test]
fn a_mass_between_grid_points_is_placed_and_weighed_there() {
    let (tx, ty, tm) = (0.716, 0.477, 3.31);
    let (dir, stdout, json) = diagnose_small_with_mass("coarse-between", (tx, ty, tm), 4);
    assert_mass_alone_near(&json, &stdout, (tx, ty, tm));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Found with the same probe (seed 6, case 9: a 1.19 kg mass at (0.456, 0.263) m, noise seed
/// 10): the mass was found (1.20 kg at its mirror image), then a region +27 % stiffer over a
/// quarter of the plate beside it, and the mass reweighed 0.82 kg beside the region. Through its
/// re-solved model the region scored below "no change" (as every stiffer region named beside a
/// mass in the probes did: −4 to −22); a finding must now beat "no change" through its
/// re-solved model too. Since a new finding must also beat what a kept finding's own kind,
/// scanned again, explains, that earlier rule rejects the region (the rule above is still
/// tested by the thin plate's mass). Asserted: the mass alone, within 0.1 m (or a mirror image)
/// and 25 %, and the region reported as rejected.
#[test]
fn a_finding_the_re_solved_model_does_not_bear_out_is_rejected() {
    let (tx, ty, tm) = (0.456, 0.263, 1.19);
    let (dir, stdout, json) = diagnose_small_with_mass("coarse-borne", (tx, ty, tm), 10);
    assert_mass_alone_near(&json, &stdout, (tx, ty, tm));
    let report = std::fs::read_to_string(dir.join("out").join("report.md")).unwrap();
    let kind = "stiffness_change (rejected: a kept finding's own kind, scanned again, explains it)";
    assert!(rejected_row_gain(&report, kind) < MIN_BIC_GAIN, "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Found with the same probe (seed 5, case 10: a 1.51 kg mass at (0.886, 1.197) m, 0.11 m from
/// the free edge x1, noise seed 11). Once the shapes put the mass at its place rather than its
/// mirror image (close modes scored as one subspace among images), a region +42 % stiffer along
/// that free edge was named beside it in round 2 (+9.9), making up for the mass being 0.04 m
/// off: with the true mass in the model nothing else is found, and a second mass beside the
/// first explained more than the strip. A new finding must now also beat what a kept finding's
/// own kind, scanned again, explains. Measured: 1.41 kg at (0.85, 1.18) m alone, calibrated
/// frequency RMS 2.69 → 1.75 Hz (with the strip 2.53). Asserted: the mass alone at its place
/// (not an image) within 0.1 m and 25 %, and the strip reported as rejected for that reason.
#[test]
fn a_finding_that_makes_up_for_a_kept_finding_off_its_place_is_rejected() {
    let (tx, ty, tm) = (0.886, 1.197, 1.51);
    let (_dir, stdout, json) = diagnose_small_with_mass("coarse-kept", (tx, ty, tm), 11);
    assert_mass_alone_near(&json, &stdout, (tx, ty, tm));
    let ((x, y), _) = place_and_mass(physics_in(&json)[0]);
    assert!((x - tx).hypot(y - ty) < 0.1, "({x}, {y}): not at its place");
    assert!(
        stdout.contains("rejected: a kept finding's own kind, scanned again"),
        "{stdout}"
    );
}

/// Recordings from another plate theory: the small plate as a Kirchhoff plate
/// (`scripts/kirchhoff_sim.py`, no mesh, noise-free in `tests/data`; noise 50 dB under the mean
/// power added per seed), against the right 12 × 18 model. The thin plate's frequencies lie
/// above the solid's by 0.4–1.1 % in the modes that twist at the free edges x0 and x1 and by
/// 0.06–0.24 % in the others; a point mass of 0.86 kg was named in six of six such recordings.
/// The twist at free edges is now a model-form column where it earns its place.
#[test]
fn a_kirchhoff_recording_of_the_right_model_gets_no_finding() {
    let set = PathBuf::from(common::data("diagnose/small-plate-kirchhoff-control"));
    let model = Model::from_toml_str(&plate(SMALL, (12, 18), "sensors = { nx = 9, ny = 13 }", ""))
        .expect("the coarse model");
    assert_no_physics(&set, &model, &[1, 2]);
}
