#!/usr/bin/env python3
"""Cross-check dampscope's universal-file (UFF) reader and writer against pyuff.

Two jobs:

  generate   pyuff writes the reference files dampscope's tests read, with the values it wrote:
               tests/data/uff/pyuff_frf.uff            (ASCII) units 164 (mm), nodes 15 and 2411,
                                                       three FRFs (58, complex double, analytic
                                                       single-mode accelerance), one time
                                                       response (58, real double), one normal
                                                       mode and one complex mode (55)
               tests/data/uff/pyuff_58b.uff            binary 58b: a time response (real double)
                                                       and an FRF (complex double; pyuff writes
                                                       half the true byte count in its header)
               tests/data/uff/pyuff_frf_expected.json  the values written (full double precision)
  check FILE [--expected JSON]
             pyuff reads FILE (e.g. one dampscope wrote) and prints every dataset; with
             --expected (the JSON dampscope's test writes beside it) every value is compared and
             the script exits 1 on a mismatch beyond the format's precision.

usage: python3 scripts/pyuff_crosscheck.py generate [--out-dir tests/data/uff]
       python3 scripts/pyuff_crosscheck.py check FILE.uff [--expected FILE.json]

Needs pyuff (pip install --user pyuff; tested with 2.5.8) and numpy.
"""
import argparse
import json
import os
import sys

import numpy as np
import pyuff

# The analytic FRFs: accelerance of one mode, H(f) = -(2 pi f)^2 A / (fn^2 - f^2 + 2j zeta f fn),
# on 0, df, ..., fmax (the grid dampscope's inverse FFT needs).
DF_HZ = 1.0
FMAX_HZ = 256.0
FRFS = [  # response node, direction, A, fn (Hz), zeta
    (1, 3, 1.0e-3, 55.0, 0.02),
    (2, 3, -2.5e-3, 120.5, 0.01),
    (3, 3, 4.0e-4, 200.25, 0.005),
]
REF = (1, 3)  # reference node and direction (+Z)
NODES_MM = [(1, (0.0, 0.0, 0.0)), (2, (250.0, 125.5, 0.0)), (3, (-100.0, 300.0, 20.0))]
TIME = dict(node=2, direction=3, fs_hz=1024.0, n=1024, f_hz=60.0, zeta=0.02)


def accelerance(f, a, fn, zeta):
    w = 2 * np.pi * f
    return -(w ** 2) * a / (fn ** 2 - f ** 2 + 2j * zeta * f * fn)


def frf_sets():
    f = np.arange(0.0, FMAX_HZ + DF_HZ / 2, DF_HZ)
    out = []
    for node, direction, a, fn, zeta in FRFS:
        h = accelerance(f, a, fn, zeta)
        out.append(dict(
            type=58, binary=0, id1=f"H {node}+Z / {REF[0]}+Z", id2="analytic single mode", id3="NONE",
            id4="NONE", id5="NONE", func_type=4, ver_num=0, load_case_id=0,
            rsp_ent_name="NONE", rsp_node=node, rsp_dir=direction, ref_ent_name="NONE",
            ref_node=REF[0], ref_dir=REF[1], ord_data_type=6, num_pts=len(f),
            abscissa_spacing=1, abscissa_min=0.0, abscissa_inc=DF_HZ, z_axis_value=0.0,
            abscissa_spec_data_type=18, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0,
            abscissa_temp_unit_exp=0, abscissa_axis_lab="Frequency",
            abscissa_axis_units_lab="Hz", ordinate_spec_data_type=12, ordinate_len_unit_exp=0,
            ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
            ordinate_axis_lab="Acceleration", ordinate_axis_units_lab="m/s^2",
            orddenom_spec_data_type=13, orddenom_len_unit_exp=0, orddenom_force_unit_exp=0,
            orddenom_temp_unit_exp=0, orddenom_axis_lab="Force", orddenom_axis_units_lab="N",
            z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
            z_axis_temp_unit_exp=0, z_axis_axis_lab="NONE", z_axis_axis_units_lab="NONE",
            data=h, x=f, spec_data_type=12))
    return f, out


def time_set(binary):
    t = TIME
    x = np.arange(t["n"]) / t["fs_hz"]
    w = 2 * np.pi * t["f_hz"]
    y = np.exp(-t["zeta"] * w * x) * np.sin(w * np.sqrt(1 - t["zeta"] ** 2) * x)
    d = dict(
        type=58, binary=binary, id1="impulse response", id2="NONE", id3="NONE", id4="NONE",
        id5="NONE", func_type=1, ver_num=0, load_case_id=0, rsp_ent_name="NONE",
        rsp_node=t["node"], rsp_dir=t["direction"], ref_ent_name="NONE", ref_node=REF[0],
        ref_dir=REF[1], ord_data_type=4, num_pts=t["n"], abscissa_spacing=1,
        abscissa_min=0.0, abscissa_inc=1 / t["fs_hz"], z_axis_value=0.0,
        abscissa_spec_data_type=17, abscissa_axis_lab="Time", abscissa_axis_units_lab="s",
        ordinate_spec_data_type=12, ordinate_axis_lab="Acceleration",
        ordinate_axis_units_lab="m/s^2", orddenom_spec_data_type=0,
        z_axis_spec_data_type=0, data=y, x=x, spec_data_type=12)
    return y, d


def shape_sets():
    nodes = np.array([n for n, _ in NODES_MM])
    r = [np.array([0.1, -0.2, 0.3]), np.array([0.0, 0.5, -0.25]), np.array([1.0, 0.75, 0.125])]
    normal = dict(
        type=55, id1="mode 1", id2="NONE", id3="NONE", id4="NONE", id5="NONE", model_type=1,
        analysis_type=2, data_ch=2, spec_data_type=8, data_type=2, n_data_per_node=3,
        r1=r[0], r2=r[1], r3=r[2], load_case=1, mode_n=1, freq=55.0, modal_m=1.5,
        modal_damp_vis=0.02, modal_damp_his=0.0, node_nums=nodes)
    fn, zeta = 120.5, 0.01
    wn = 2 * np.pi * fn
    eig = complex(-zeta * wn, wn * np.sqrt(1 - zeta ** 2))
    c = [v * (1 - 0.5j) for v in r]
    cplx = dict(
        type=55, id1="mode 2", id2="NONE", id3="NONE", id4="NONE", id5="NONE", model_type=1,
        analysis_type=3, data_ch=2, spec_data_type=8, data_type=5, n_data_per_node=3,
        r1=c[0], r2=c[1], r3=c[2], load_case=1, mode_n=2, eig=eig, modal_a=0j, modal_b=0j,
        node_nums=nodes)
    return (r, c, eig), [normal, cplx]


def generate(out_dir):
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "pyuff_frf.uff")
    if os.path.exists(path):
        os.remove(path)
    uf = pyuff.UFF(path)
    units = pyuff.prepare_164(units_code=5, units_description="mm (milli newton)",
                              temp_mode=2, length=1000.0, force=1000.0, temp=1.0,
                              temp_offset=273.15)
    labels = [n for n, _ in NODES_MM]
    xyz = np.array([p for _, p in NODES_MM])
    n15 = pyuff.prepare_15(node_nums=labels, def_cs=[0] * 3, disp_cs=[0] * 3, color=[1] * 3,
                           x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2])
    n2411 = pyuff.prepare_2411(node_nums=np.array([10 + n for n in labels]),
                               def_cs=np.zeros(3, int), disp_cs=np.zeros(3, int),
                               color=np.ones(3, int), x=xyz[:, 0] / 3, y=xyz[:, 1] / 7,
                               z=xyz[:, 2])
    f, frfs = frf_sets()
    y, t = time_set(0)
    (r, c, eig), shapes = shape_sets()
    uf.write_sets([units, n15, n2411] + frfs + [t] + shapes, mode="add")
    bpath = os.path.join(out_dir, "pyuff_58b.uff")
    if os.path.exists(bpath):
        os.remove(bpath)
    ub = pyuff.UFF(bpath)
    ub.write_sets([time_set(1)[1], dict(frfs[1], binary=1)], mode="add")
    expected = {
        "comment": "written by scripts/pyuff_crosscheck.py generate with pyuff "
                   + pyuff.__version__ + "; full double precision",
        "units": {"code": 5, "length_factor": 1000.0},
        "nodes15": [{"label": n, "xyz_mm": list(p)} for n, p in NODES_MM],
        "nodes2411": [{"label": 10 + n, "xyz": [p[0] / 3, p[1] / 7, p[2]]} for n, p in NODES_MM],
        "frf": {"df_hz": DF_HZ, "fmax_hz": FMAX_HZ, "n": len(f), "reference": list(REF),
                "channels": [{"node": node, "direction": d, "a": a, "fn_hz": fn, "zeta": z,
                              "re": list(accelerance(f, a, fn, z).real),
                              "im": list(accelerance(f, a, fn, z).imag)}
                             for node, d, a, fn, z in FRFS]},
        "time": dict(TIME, values=list(y)),
        "normal_mode": {"mode": 1, "frequency_hz": 55.0, "modal_mass": 1.5, "zeta": 0.02,
                        "r": [list(v) for v in r]},
        "complex_mode": {"mode": 2, "eig": [eig.real, eig.imag], "fn_hz": 120.5, "zeta": 0.01,
                         "re": [list(v.real) for v in c], "im": [list(v.imag) for v in c]},
    }
    with open(os.path.join(out_dir, "pyuff_frf_expected.json"), "w") as fh:
        json.dump(expected, fh)
    for p in (path, bpath):
        print(f"wrote {p} ({os.path.getsize(p)} bytes)")
    print(f"wrote {os.path.join(out_dir, 'pyuff_frf_expected.json')}")


def rel_err(a, b):
    a, b = np.asarray(a, complex), np.asarray(b, complex)
    scale = max(np.max(np.abs(b)), 1e-300)
    return float(np.max(np.abs(a - b)) / scale)


def check(path, expected_path):
    sets = pyuff.UFF(path).read_sets()
    if isinstance(sets, dict):
        sets = [sets]
    print(f"{path}: {len(sets)} datasets (pyuff {pyuff.__version__})")
    for k, s in enumerate(sets):
        t = s.get("type")
        if t == 58:
            kind = {1: "time response", 4: "FRF"}.get(s["func_type"], f"type {s['func_type']}")
            d = np.asarray(s["data"])
            print(f"  [{k}] 58{'b' if s.get('binary') else ''} {kind}: response {s['rsp_node']}"
                  f"/{s['rsp_dir']}, reference {s['ref_node']}/{s['ref_dir']}, {len(d)} points,"
                  f" x {s['x'][0]:g}..{s['x'][-1]:g}, first {d[0]:.6g}, last {d[-1]:.6g},"
                  f" id1 {s['id1']!r}")
        elif t == 55:
            print(f"  [{k}] 55 analysis {s['analysis_type']}, mode {s.get('mode_n')}, "
                  f"freq {s.get('freq')}, eig {s.get('eig')}, {len(s['node_nums'])} nodes, "
                  f"r1 {np.asarray(s['r1'])[:3]}")
        elif t in (15, 2411):
            print(f"  [{k}] {t} nodes {list(np.asarray(s['node_nums']).astype(int))}, "
                  f"x {list(np.asarray(s['x']))}")
        else:
            print(f"  [{k}] dataset {t}")
    if not expected_path:
        return 0
    with open(expected_path) as fh:
        exp = json.load(fh)
    failures = []
    by_node = {(s["func_type"], s["rsp_node"]): s for s in sets if s.get("type") == 58}
    for ch in exp.get("functions", []):
        s = by_node.get((ch["function_type"], ch["node"]))
        if s is None:
            failures.append(f"function type {ch['function_type']} at node {ch['node']}: missing")
            continue
        want = np.asarray(ch["re"]) + 1j * np.asarray(ch.get("im", np.zeros(len(ch["re"]))))
        e = rel_err(s["data"], want)
        ex = rel_err(s["x"], np.asarray(ch["x"]))
        print(f"  check function {ch['function_type']} node {ch['node']}: "
              f"max rel error {e:.2e} (values), {ex:.2e} (abscissa)")
        if e > 1e-10 or ex > 1e-6 or s["rsp_dir"] != ch["direction"]:
            failures.append(f"function at node {ch['node']}: errors {e:.2e}, {ex:.2e}")
    shapes = [s for s in sets if s.get("type") == 55]
    for m, s in zip(exp.get("shapes", []), shapes):
        got = np.concatenate([np.asarray(s[f"r{i}"]) for i in (1, 2, 3)])
        want = np.asarray(m["re"]) + 1j * np.asarray(m["im"])
        e = rel_err(got, want.reshape(-1, 3).T.ravel())
        f = s["freq"] if s["analysis_type"] == 2 else abs(s["eig"]) / (2 * np.pi)
        ef = abs(f - m["frequency_hz"]) / m["frequency_hz"]
        print(f"  check shape mode {m['mode']}: max rel error {e:.2e} (values), {ef:.2e} (f)")
        if e > 1e-5 or ef > 1e-5:
            failures.append(f"shape {m['mode']}: errors {e:.2e}, {ef:.2e}")
    nodes = [s for s in sets if s.get("type") in (15, 2411)]
    if "nodes" in exp:
        got = {int(n): (x, y, z) for s in nodes
               for n, x, y, z in zip(s["node_nums"], s["x"], s["y"], s["z"])}
        for n in exp["nodes"]:
            e = rel_err(got.get(n["label"], (np.nan,) * 3), n["xyz"])
            if not e <= 1e-12:
                failures.append(f"node {n['label']}: rel error {e:.2e}")
        print(f"  check {len(exp['nodes'])} nodes: {'ok' if not failures else 'see below'}")
    for f in failures:
        print("  MISMATCH", f)
    print("pyuff cross-check:", "FAILED" if failures else "all values agree")
    return 1 if failures else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate")
    g.add_argument("--out-dir", default=os.path.join("tests", "data", "uff"))
    c = sub.add_parser("check")
    c.add_argument("file")
    c.add_argument("--expected")
    a = ap.parse_args()
    if a.cmd == "generate":
        generate(a.out_dir)
        return 0
    return check(a.file, a.expected)


if __name__ == "__main__":
    sys.exit(main())
