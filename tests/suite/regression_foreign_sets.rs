//! Found by writing recording sets as other labs' tools write them (FORMATS.md §1), each valid
//! by the contract: a `responses.csv` whose sensor ids are numbers (`1001,1002`) had its header
//! read as a first sample of 1001 — 20 000 times the signal, D 0.42 for 0.01, one flag; columns
//! named by sensor id in another order than `sensors.csv` were refused; a quoted id holding a
//! comma split the header; quoted numbers (pandas' `QUOTE_ALL`) were refused; ids starting with
//! `#` were read as comments (a set of "0 sensors"); a `meta.json` with a byte-order mark, a
//! `null`, a key given twice or a non-numeric informative `snr_db` was refused.

use std::collections::HashMap;
use std::path::Path;
use std::process::Output;

use crate::common::{decaying_sines, fresh_dir, run_dampscope as dampscope};

const FS_HZ: f64 = 4000.0;

/// Channel k decays at its own frequency, so a channel read in another's place shows.
const MODES: [(f64, f64); 3] = [(100.0, 0.01), (250.0, 0.005), (400.0, 0.002)];

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The samples of channel k: one decaying mode, peak about 0.05.
fn channel(k: usize) -> Vec<f64> {
    let (f, zeta) = MODES[k];
    decaying_sines(&[(f, zeta, 0.05, 0.0)], FS_HZ, 2.0)
}

/// Writes a set: `sensors.csv` with `ids` in channel order, `responses.csv` with a header of
/// `header` (the columns' names, in file order, a time column first when `time`), the columns
/// being channels `order` (indices into `ids`), each cell formatted by `cell`.
fn write_set(
    dir: &Path,
    ids: &[&str],
    header: &str,
    order: &[usize],
    time: bool,
    cell: &dyn Fn(f64) -> String,
) {
    std::fs::create_dir_all(dir).unwrap();
    let mut sensors = String::from("id,x,y\n");
    for (k, id) in ids.iter().enumerate() {
        sensors.push_str(&format!("{id},{},0.5\n", 0.1 * (k + 1) as f64));
    }
    std::fs::write(dir.join("sensors.csv"), sensors).unwrap();
    let data: Vec<Vec<f64>> = order.iter().map(|&k| channel(k)).collect();
    let mut text = format!("{header}\n");
    for i in 0..data[0].len() {
        let mut cells: Vec<String> = data.iter().map(|c| cell(c[i])).collect();
        if time {
            cells.insert(0, cell(i as f64 / FS_HZ));
        }
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    std::fs::write(dir.join("responses.csv"), text).unwrap();
}

/// Runs `analyze` on `set` (octave bands, which hold one mode each) and returns, per channel,
/// the corrected D of the band holding that channel's mode (`None`: no such row or no number).
fn damping_per_channel(set: &Path, ids: &[&str]) -> (Output, Vec<Option<f64>>) {
    let o = dampscope(
        &["analyze", set.to_str().unwrap(), "--bands", "octave"],
        b"",
    );
    let mut table = csv::Reader::from_reader(o.stdout.as_slice());
    let header: Vec<String> = table
        .headers()
        .map(|h| h.iter().map(String::from).collect())
        .unwrap_or_default();
    let rows: Vec<HashMap<String, String>> = table
        .records()
        .map(|r| {
            header
                .iter()
                .cloned()
                .zip(r.unwrap().iter().map(String::from))
                .collect()
        })
        .collect();
    let found = ids
        .iter()
        .enumerate()
        .map(|(k, id)| {
            let f = MODES[k].0;
            rows.iter()
                .find(|r| {
                    r["channel"] == *id
                        && r["f_lo"].parse::<f64>().unwrap() <= f
                        && f < r["f_hi"].parse::<f64>().unwrap()
                })
                .and_then(|r| r["damping_ratio_corrected"].parse().ok())
        })
        .collect();
    (o, found)
}

fn assert_each_channel_right(set: &Path, ids: &[&str]) -> Output {
    let (o, found) = damping_per_channel(set, ids);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for (k, d) in found.iter().enumerate() {
        let want = MODES[k].1;
        let d = d.unwrap_or_else(|| panic!("channel {}: no D\n{}", ids[k], stderr(&o)));
        assert!(
            (d / want - 1.0).abs() < 0.05,
            "channel {}: D {d} for {want}",
            ids[k]
        );
    }
    o
}

#[test]
fn numeric_sensor_ids_make_a_header_not_a_first_sample() {
    let dir = fresh_dir("foreign-numeric-ids");
    let ids = ["1001", "1002", "1003"];
    let plain = |v: f64| format!("{v:e}");
    // No time column: meta.json gives the rate, and the header is all numbers.
    let set = dir.join("no-time");
    write_set(&set, &ids, "1001,1002,1003", &[0, 1, 2], false, &plain);
    std::fs::write(set.join("meta.json"), format!("{{\"fs\": {FS_HZ}}}")).unwrap();
    assert_each_channel_right(&set, &ids);
    // The onset is the first sample's (0 s), not a spike's: the rows start at 0.
    let set = dir.join("time");
    write_set(&set, &ids, "time,1001,1002,1003", &[0, 1, 2], true, &plain);
    assert_each_channel_right(&set, &ids);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn columns_named_by_sensor_id_in_another_order_are_taken_by_name() {
    let dir = fresh_dir("foreign-permuted");
    let ids = ["S1", "S2", "S3"];
    let set = dir.join("set");
    // The file holds S3, S1, S2: each column's data is its own sensor's.
    write_set(&set, &ids, "time,S3,S1,S2", &[2, 0, 1], true, &|v| {
        format!("{v:e}")
    });
    assert_each_channel_right(&set, &ids);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn quoted_ids_quoted_numbers_and_hash_ids_are_read() {
    let dir = fresh_dir("foreign-quoted");
    // A quoted id holding the separator, an id with quotes, one starting with '#'; every
    // number quoted as pandas' QUOTE_ALL writes it.
    let ids = ["\"Acc, top\"", "#2", "\"say \"\"hi\"\"\""];
    let names = ["Acc, top", "#2", "say \"hi\""];
    let set = dir.join("set");
    let header = format!("\"time\",{}", ids.join(","));
    write_set(&set, &ids, &header, &[0, 1, 2], true, &|v| {
        format!("\"{v:e}\"")
    });
    let (o, found) = damping_per_channel(&set, &names);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("\"Acc, top\",") && text.contains("#2,"),
        "{text}"
    );
    for (k, d) in found.iter().enumerate() {
        let d = d.unwrap_or_else(|| panic!("channel {}: no D", names[k]));
        assert!((d / MODES[k].1 - 1.0).abs() < 0.05, "{}: {d}", names[k]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn meta_json_as_other_tools_write_it_is_read() {
    let dir = fresh_dir("foreign-meta");
    let ids = ["A", "B", "C"];
    let set = dir.join("set");
    write_set(&set, &ids, "A,B,C", &[0, 1, 2], false, &|v| {
        format!("{v:e}")
    });
    // A byte-order mark, a null, a key given twice (the last counts), an informative key of
    // the wrong type.
    let meta = format!(
        "\u{feff}{{\"fs\": 1000, \"kind\": null, \"snr_db\": \"unknown\", \"fs\": {FS_HZ}}}"
    );
    std::fs::write(set.join("meta.json"), meta).unwrap();
    let o = assert_each_channel_right(&set, &ids);
    assert!(stderr(&o).contains("snr_db"), "{}", stderr(&o));
    // A key the analysis needs, of the wrong type, is an error naming it.
    std::fs::write(set.join("meta.json"), "{\"fs\": \"fast\"}").unwrap();
    let (o, _) = damping_per_channel(&set, &ids);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("fs:"), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Found the same way: a response cut at 0.5 s and zero-padded to 2 s (as exports pad to a
/// fixed length) gave D 0.0120 for 0.0100 at 100 Hz (T60 1.1 s, so 0.5 s holds 27 dB of it),
/// flagged only `nonlinear_decay`, where the same 0.5 s unpadded gives `too_short`: the exact
/// zeros looked like a decay that reached −∞ dB. The record now ends at its last sample with
/// energy, padded or not.
#[test]
fn a_record_zero_padded_after_its_cut_is_as_short_as_the_cut() {
    let dir = fresh_dir("foreign-zero-padded");
    let ids = ["S1", "S2", "S3"];
    let cut = (0.5 * FS_HZ) as usize;
    for (name, padded) in [("padded", true), ("cut", false)] {
        let set = dir.join(name);
        write_set(&set, &ids, "time,S1,S2,S3", &[0, 1, 2], true, &|v| {
            format!("{v:e}")
        });
        let text = std::fs::read_to_string(set.join("responses.csv")).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        for (i, line) in lines.iter_mut().enumerate().skip(1 + cut) {
            *line = format!("{:e},0,0,0", (i - 1) as f64 / FS_HZ);
        }
        if !padded {
            lines.truncate(1 + cut);
        }
        std::fs::write(set.join("responses.csv"), lines.join("\n") + "\n").unwrap();
        // The default 50 Hz bands: 75–125 Hz holds the 100 Hz mode alone.
        let o = dampscope(&["analyze", set.to_str().unwrap()], b"");
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout);
        let row = text
            .lines()
            .find(|l| l.starts_with("S1,") && l.contains(",75.000000,125.000000,"))
            .unwrap_or_else(|| panic!("no 75–125 Hz row:\n{text}"));
        assert!(row.ends_with("too_short"), "{name}: {row}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Found piping CSV that ends every line with its separator (`time,s0,s1,`): a third,
/// nameless channel of empty cells appeared, flagged `non_finite_input` in every band, and the
/// run exited 3 ("channel(s) : no estimates").
#[test]
fn a_separator_ending_every_line_opens_no_channel() {
    let (a, b) = (channel(0), channel(1));
    let mut text = String::from("time,s0,s1,\n");
    for i in 0..a.len() {
        text.push_str(&format!("{:e},{:e},{:e},\n", i as f64 / FS_HZ, a[i], b[i]));
    }
    let o = dampscope(&["analyze", "-", "--bands", "octave"], text.as_bytes());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let mut table = csv::Reader::from_reader(o.stdout.as_slice());
    let channels: std::collections::BTreeSet<String> =
        table.records().map(|r| r.unwrap()[0].to_string()).collect();
    assert_eq!(channels.into_iter().collect::<Vec<_>>(), ["s0", "s1"]);
}
