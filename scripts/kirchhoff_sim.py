#!/usr/bin/env python3
"""Independent plate simulator: Kirchhoff thin plate, Rayleigh-Ritz with a Legendre basis.

Purpose: test recordings for `dampscope diagnose` that come from a different plate theory
(Kirchhoff, out-of-plane deflection w(x, y) only) and a different discretisation (a few large
C1 spectral cells of high polynomial degree) than dampscope's 8-node-hexahedron finite elements.

Input : a plate model TOML (docs FORMATS.md section 3; [mesh] is ignored).
Output: a recording set (FORMATS.md section 1): responses.wav, sensors.csv, excitation.csv,
        meta.json; acceleration in z per unit force impulse ("m/s^2 per N s").

  python3 scripts/kirchhoff_sim.py MODEL.toml --out DIR --fs 1000 --seconds 3 \
          [--snr-db 50 --seed 1] [--sensors FILE.csv] [--print-modes 200]

Method (details in the comments of each step):
 * basis: w(x, y) = sum_ij a_ij psi_i(x) phi_j(y), a tensor product of two 1D bases. For a
   plain plate each 1D basis is all polynomials of degree <= N on [0, L] (orthonormal
   Legendre). Patch boundaries and point-mass coordinates become breakpoints: the 1D basis is
   then piecewise polynomial, C1 at the breakpoints (Hermite ends + Legendre bubbles), which
   lets the curvature jump where the stiffness jumps. A pinned edge (w = 0 on the line) is
   imposed exactly by dropping the 1D end-value function (w then vanishes on the whole edge
   line); free edges need nothing; an edge spring is an energy term, pinned or not.
 * energies: bending energy 1/2 int D [w_xx^2 + w_yy^2 + 2 nu w_xx w_yy + 2 (1-nu) w_xy^2] and
   kinetic energy 1/2 int rho h w_t^2 are integrated per rectangular cell (the plate cut along
   every patch boundary; a cell takes the properties of the LAST patch covering it) with
   Gauss-Legendre quadrature, exact for the polynomial integrands, as Kronecker products of 1D
   matrices. Point masses add m b b^T, edge springs k int w^2 ds along the edge line.
 * damping: per region K_r (1 + j g_r); an SLS region multiplies its K_r (assembled with e_inf)
   by E*(w)/e_inf = 1 + (e/e_inf) jw tau/(1 + jw tau); Rayleigh C = alpha M + beta K0 with
   K0 = sum of region stiffnesses at reference moduli (e_inf for SLS) plus edge springs (the
   same conventions as dampscope's simulator). Edge springs carry no loss factor.
 * response: the real undamped modes of (K0, M) in the full Ritz basis; the damped problem is
   projected onto the modes below a cut-off (default 2.5 x max(fs/2, --print-modes)) plus
   residual vectors K0^-1 K_t Phi for the non-proportionally damped terms t, and written in
   first-order (state-space) form, with one set of internal variables q per SLS region
   (tau q' = u - q, exact for the SLS). One eigen-decomposition gives poles s_n and residues:
   H(jw) = -w^2 [ sum_n R_n/(jw - s_n) + static flexibility the reduced basis misses ].
   The FRF is evaluated on an FFT grid whose period is >= 4 x the record and >= the record +
   the longest T60 of the poles below fs/2 (at most 200 s), tapered by a half-cosine over the
   top 15 % below fs/2 (anti-aliasing), inverse-FFT'd; the first --seconds are kept.
"""
import argparse
import json
import math
import os
import sys
import time
import tomllib

# One BLAS thread unless the caller says otherwise: the dense eigen-solvers are then as fast as
# with two threads on an idle machine, up to 10x faster on a busy one (no spin-waiting), and
# the results do not depend on the thread count (deterministic output).
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402  (after the thread settings)
import scipy.linalg as sla  # noqa: E402
from numpy.polynomial import legendre as leg  # noqa: E402
from scipy.io import wavfile  # noqa: E402

EDGES = ("x0", "x1", "y0", "y1")
TAPER_FRACTION = 0.15      # half-cosine taper over the top 15 % of the band below fs/2
PERIOD_FACTOR = 4.0        # FFT period >= 4 x the record length ...
T60_DB = 60.0              # ... and >= the record + the longest T60 of the poles below fs/2
MAX_PERIOD_S = 200.0       # cap for (nearly) undamped models (memory: fs * 200 s * channels)
P_MIN, P_EXTRA = 8, 4      # degree of an interval of length h: max(P_MIN, round(N h/L) + P_EXTRA)


def log(*a):
    print(*a, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------------------------
# Model
# ----------------------------------------------------------------------------------------------
def read_sensors(path):
    """sensors.csv: header id,x,y[,z][,dir]; returns a list of (id, x, y)."""
    with open(path, encoding="utf-8") as fh:
        rows = [ln.strip() for ln in fh if ln.strip()]
    head = [h.strip() for h in rows[0].split(",")]
    ix, iy, ii = head.index("x"), head.index("y"), head.index("id")
    idir = head.index("dir") if "dir" in head else None
    out = []
    for r in rows[1:]:
        c = [v.strip() for v in r.split(",")]
        if idir is not None and c[idir] not in ("", "z"):
            raise SystemExit(f"{path}: only dir = z sensors are supported (Kirchhoff w only)")
        out.append((c[ii], float(c[ix]), float(c[iy])))
    return out


def load_model(path, sensors_override=None):
    """Reads the TOML model into a plain dict with everything the simulator needs."""
    with open(path, "rb") as fh:
        t = tomllib.load(fh)
    base_dir = os.path.dirname(os.path.abspath(path))
    pl, mat = t["plate"], t["material"]
    lx, ly, h = float(pl["lx"]), float(pl["ly"]), float(pl["thickness"])
    base = {k: float(mat[k]) for k in ("youngs_modulus", "poisson", "density")}
    base["loss_factor"] = float(mat.get("loss_factor", 0.0))
    base["sls"] = None
    regions = [base]                      # region 0 = plate, region p+1 = patch p
    rects = []
    for p in t.get("patch", []):
        r = dict(base)                    # a patch overrides the PLATE's properties
        for k in ("youngs_modulus", "poisson", "density", "loss_factor"):
            if k in p:
                r[k] = float(p[k])
        if "sls" in p:
            s = {k: float(p["sls"][k]) for k in ("e", "e_inf", "eta")}
            if min(s.values()) <= 0:
                raise SystemExit("patch sls: e, e_inf and eta must be > 0")
            r["sls"] = s
            r["youngs_modulus"] = s["e_inf"]   # reference modulus of an SLS region
        regions.append(r)
        rects.append((sorted(map(float, p["x"])), sorted(map(float, p["y"]))))
    pinned = list(t.get("supports", {}).get("pinned_edges", []))
    springs = [(s["edge"], float(s["stiffness_per_length"])) for s in t.get("edge_spring", [])]
    for e in pinned + [s[0] for s in springs]:
        if e not in EDGES:
            raise SystemExit(f"unknown edge {e!r} (allowed: {EDGES})")
    masses = [(float(m["x"]), float(m["y"]), float(m["mass"])) for m in t.get("point_mass", [])]
    ex = t["excitation"]
    if ex.get("dir", "z") != "z":
        raise SystemExit("only z excitation is supported (Kirchhoff plate)")
    ray = t.get("damping", {}).get("rayleigh", {})
    alpha, beta = float(ray.get("alpha", 0.0)), float(ray.get("beta", 0.0))
    # Sensors: --sensors FILE, else [output] sensors = {file} or {nx, ny} (edge to edge, x fastest).
    spec = t.get("output", {}).get("sensors", {})
    if sensors_override:
        sensors = read_sensors(sensors_override)
    elif "file" in spec:
        f = spec["file"]
        sensors = read_sensors(f if os.path.isabs(f) else os.path.join(base_dir, f))
    else:
        if "nx" not in spec:
            raise SystemExit("no sensors: give [output] sensors = {file} or {nx, ny}, or --sensors")
        nx, ny = int(spec["nx"]), int(spec["ny"])
        cx = lambda i, n, L: 0.5 * L if n == 1 else L * i / (n - 1)
        sensors = [(f"s{iy * nx + ix:04d}", cx(ix, nx, lx), cx(iy, ny, ly))
                   for iy in range(ny) for ix in range(nx)]
    pts = [(s[1], s[2]) for s in sensors] + [(m[0], m[1]) for m in masses] + \
          [(float(ex["x"]), float(ex["y"]))]
    for x, y in pts:
        if not (-1e-9 <= x <= lx + 1e-9 and -1e-9 <= y <= ly + 1e-9):
            raise SystemExit(f"point ({x}, {y}) lies outside the plate")
    return dict(lx=lx, ly=ly, h=h, regions=regions, rects=rects, pinned=pinned,
                springs=springs, masses=masses, alpha=alpha, beta=beta, sensors=sensors,
                exc=(float(ex["x"]), float(ex["y"]), float(ex.get("force", 1.0))))


# ----------------------------------------------------------------------------------------------
# 1D basis: piecewise polynomials, C1 at the breakpoints, L2-orthonormal on [0, L]
# ----------------------------------------------------------------------------------------------
# Without patches there is one interval and the basis spans all polynomials of degree <= N
# (a global Legendre basis). A patch boundary is a breakpoint: across it the basis is C1 but
# the curvature may jump, as moment continuity D1 w''(-) = D2 w''(+) requires; with a global
# polynomial the eigenvalues of a plate with a stiffness jump converge only like ~1/N (measured:
# 0.2 % at N = 40 for a x0.5 patch), with the breakpoints like a smooth problem until the
# patch corners' weak singularities show. The tensor product of two such 1D bases is conforming
# for Kirchhoff plates (w, w_x, w_y, w_xy continuous across cell lines; a C1 spectral element).
HERMITE = np.array([[2, -3, 0, 1], [1, -1, -1, 1], [2, 3, 0, -1], [-1, -1, 1, 1]]) / 4.0
# Cubic Hermite shapes on xi in [-1, 1] (power-series coefficients): value at the left end,
# slope at the left end, value at the right end, slope at the right end (slopes x h/2 below).


class Basis1D:
    def __init__(self, L, breaks, degree, pin_lo, pin_hi, ratios):
        self.L, self.b = L, np.asarray(breaks, float)
        h = np.diff(self.b)
        ne = h.size
        # Degree per interval: N for a single interval, else proportional to length (times the
        # interval's bending-wavenumber ratio, see build) plus P_EXTRA, at most 64.
        self.p = [degree] if ne == 1 else \
            [min(64, max(P_MIN, round(degree * r * he / L) + P_EXTRA)) for he, r in zip(h, ratios)]
        self.h = h
        # Bubbles (value and slope zero at both ends): the orthonormal null space of these four
        # end conditions in the orthonormal Legendre basis of each interval.
        self.Q, self.off = [], []
        nraw = 2 * (ne + 1)
        for p in self.p:
            k = np.arange(p + 1)
            sc = np.sqrt(k + 0.5)
            dp = k * (k + 1) / 2.0                  # P_k'(1); P_k(-1) = (-1)^k, P_k'(-1) = (-1)^(k+1) P_k'(1)
            ends = np.vstack([(-1.0) ** k, (-1.0) ** (k + 1) * dp, np.ones(p + 1), dp]) * sc
            self.Q.append(sla.null_space(ends))
            self.off.append(nraw)
            nraw += p - 3
        self.nraw = nraw
        cols = [c for c in range(nraw) if not ((pin_lo and c == 0) or (pin_hi and c == 2 * ne))]
        self.cols = np.array(cols)
        # Orthonormalise in L2(0, L) (symmetric: T = G^-1/2), so that a homogeneous plate's mass
        # matrix is rho h I. Linear combinations keep w = 0 at a pinned end.
        self.T = np.eye(len(cols))          # (raw functions while G is integrated)
        G = sum(self.interval(e)["00"] for e in range(ne))
        ev, U = sla.eigh(G)
        self.T = U / np.sqrt(ev)
        self.n = self.T.shape[1]

    def _raw(self, e, xi, deriv):
        """Raw (un-orthonormalised) basis functions' deriv-th x-derivative at local xi of interval e."""
        h, p = self.h[e], self.p[e]
        out = np.zeros((xi.size, self.nraw))
        herm = [np.polynomial.polynomial.polyder(c, deriv) if deriv else c for c in HERMITE]
        for i, c in enumerate(herm):
            out[:, 2 * e + i] = np.polynomial.polynomial.polyval(xi, c) * (h / 2 if i % 2 else 1)
        if deriv == 0:
            V = leg.legvander(xi, p)
        else:
            V = leg.legvander(xi, p - deriv) @ leg.legder(np.eye(p + 1), deriv, axis=0)
        out[:, self.off[e]:self.off[e] + p - 3] = (V * np.sqrt(np.arange(p + 1) + 0.5)) @ self.Q[e]
        return out[:, self.cols] * (2.0 / h) ** deriv

    def eval(self, x, deriv=0):
        """Values (deriv 0, 1, 2 in x) of the basis at points x: shape (len(x), n)."""
        x = np.atleast_1d(np.asarray(x, float))
        e = np.clip(np.searchsorted(self.b, x, side="right") - 1, 0, self.h.size - 1)
        out = np.zeros((x.size, self.T.shape[0]))
        for k in np.unique(e):
            xi = 2.0 * (x[e == k] - self.b[k]) / self.h[k] - 1.0
            out[e == k] = self._raw(k, xi, deriv)
        return out @ self.T

    def interval(self, e):
        """Over interval e: int psi^(p) psi^(q) dx for (p, q) in 00, 11, 22, 20 (exact Gauss)."""
        g, wg = leg.leggauss(self.p[e] + 2)
        w = 0.5 * self.h[e] * wg
        V = [self._raw(e, g, d) @ self.T for d in range(3)]
        m = lambda p, q: (V[p] * w[:, None]).T @ V[q]
        return {"00": m(0, 0), "11": m(1, 1), "22": m(2, 2), "20": m(2, 0)}


# ----------------------------------------------------------------------------------------------
# Ritz system
# ----------------------------------------------------------------------------------------------
def default_degree(model, fmax_hz):
    """Degree from the plate's bending wavenumber k at fmax: N = ceil(kappa + 14), kappa = k L/2
    with L = max(lx, ly) (a Legendre series resolves sin(kappa xi) once N > kappa); >= 30, <= 64.
    Measured: N = 30 converges every mode below 600 Hz of the reference plate to < 1e-3 %."""
    r = model["regions"][0]
    D = r["youngs_modulus"] * model["h"] ** 3 / (12 * (1 - r["poisson"] ** 2))
    k = ((2 * math.pi * fmax_hz) ** 2 * r["density"] * model["h"] / D) ** 0.25
    kappa = k * max(model["lx"], model["ly"]) / 2
    return int(min(64, max(30, math.ceil(kappa + 14))))


def build(model, degree):
    """Assembles M, the region stiffnesses K_r (at reference moduli), the edge-spring stiffness,
    and the basis evaluator. Returns a dict."""
    lx, ly, h = model["lx"], model["ly"], model["h"]
    pin = set(model["pinned"])
    # Breakpoints: the plate cut along every patch boundary (cells = rectangles of one region)
    # and through every point mass (its r^2 log r singularity then sits at a cell corner, which
    # doubles the convergence rate: 0.03 % -> 6e-4 % at N = 30 for the 2 kg mass, 600 Hz).
    def cuts(L, i):
        out = [0.0]
        vals = [v for r in model["rects"] for v in r[i]] + [m[i] for m in model["masses"]]
        for v in sorted(v for v in vals if 1e-6 * L < v < L * (1 - 1e-6)):
            if v - out[-1] > 1e-6 * L:      # merge cuts closer than 1e-6 L
                out.append(v)
        return out + [L]
    xs, ys = cuts(lx, 0), cuts(ly, 1)
    region = np.zeros((len(xs) - 1, len(ys) - 1), int)      # region of each cell
    for i, (xa, xb) in enumerate(zip(xs[:-1], xs[1:])):
        for j, (ya, yb) in enumerate(zip(ys[:-1], ys[1:])):
            xc, yc = 0.5 * (xa + xb), 0.5 * (ya + yb)
            for p, (rx, ry) in enumerate(model["rects"]):   # the last covering patch wins
                if rx[0] <= xc <= rx[1] and ry[0] <= yc <= ry[1]:
                    region[i, j] = p + 1
    # A softer or heavier patch has a shorter bending wavelength: its intervals get a degree
    # raised by the wavenumber ratio (rho_r D_0 / rho_0 D_r)^(1/4), clipped to [1, 2]. (A far
    # softer patch, e.g. a polymer, has local modes this does not resolve: see the limitations.)
    wk = lambda r: (r["density"] / (r["youngs_modulus"] * h ** 3 / (12 * (1 - r["poisson"] ** 2)))) ** 0.25
    ratio = np.clip([wk(r) / wk(model["regions"][0]) for r in model["regions"]], 1.0, 2.0)
    bx = Basis1D(lx, xs, degree, "x0" in pin, "x1" in pin, ratio[region].max(axis=1))
    by = Basis1D(ly, ys, degree, "y0" in pin, "y1" in pin, ratio[region].max(axis=0))
    n = bx.n * by.n
    Ax = [bx.interval(i) for i in range(len(xs) - 1)]
    Ay = [by.interval(j) for j in range(len(ys) - 1)]
    nreg = len(model["regions"])
    Kr = [np.zeros((n, n)) for _ in range(nreg)]
    M = np.zeros((n, n))
    used = [False] * nreg
    for i in range(len(xs) - 1):
        for j in range(len(ys) - 1):
            reg = region[i, j]
            r = model["regions"][reg]
            used[reg] = True
            E, nu = r["youngs_modulus"], r["poisson"]
            D = E * h ** 3 / (12 * (1 - nu ** 2))
            X, Y = Ax[i], Ay[j]
            # Bending energy density with this region's nu (w_xx w_yy appears twice).
            Kr[reg] += D * (np.kron(X["22"], Y["00"]) + np.kron(X["00"], Y["22"])
                            + nu * (np.kron(X["20"], Y["20"].T) + np.kron(X["20"].T, Y["20"]))
                            + 2 * (1 - nu) * np.kron(X["11"], Y["11"]))
            M += r["density"] * h * np.kron(X["00"], Y["00"])
    point = lambda x, y: np.kron(bx.eval([x])[0], by.eval([y])[0])
    for x, y, m in model["masses"]:
        b = point(x, y)
        M += m * np.outer(b, b)
    Ks = np.zeros((n, n))
    fullx, fully = sum(A["00"] for A in Ax), sum(A["00"] for A in Ay)
    for e, k in model["springs"]:   # k int w^2 ds along the edge line (zero on a pinned edge)
        if e[0] == "y":
            v = by.eval([0.0 if e == "y0" else ly])[0]
            Ks += k * np.kron(fullx, np.outer(v, v))
        else:
            v = bx.eval([0.0 if e == "x0" else lx])[0]
            Ks += k * np.kron(np.outer(v, v), fully)
    sym = lambda A: 0.5 * (A + A.T)
    return dict(M=sym(M), Kr=[sym(K) for K in Kr], used=used, Ks=sym(Ks), point=point,
                n=n, degree=degree)


def undamped_modes(sysm, f_cut):
    """Real modes of (K0, M) below f_cut in the full Ritz basis: lambda = omega^2 ascending, Phi
    M-orthonormal. Solved as M v = mu K0 v (mu = 1/lambda): the rounding error is then relative
    to the largest mu, i.e. to the LOWEST modes, which stay accurate to ~1e-7 even at degree 60
    (eigh(K0, M) loses ~eps * lambda_max / lambda_1 ~ 1e-4 there). Needs K0 positive definite."""
    K0 = sum(sysm["Kr"]) + sysm["Ks"]
    try:
        mu, v = sla.eigh(sysm["M"], K0, subset_by_value=((2 * math.pi * f_cut) ** -2, np.inf),
                         driver="gvx")
    except np.linalg.LinAlgError:
        raise SystemExit("the model has rigid-body modes (not supported): pin or spring an edge")
    mu, v = mu[::-1], v[:, ::-1]
    return 1.0 / mu, v / np.sqrt(mu)


def reduced_basis(model, sysm, lam, Phi, f_cut):
    """Real modes below f_cut plus residual vectors K0^-1 K_t Phi_kept for every stiffness term
    t whose damping differs from the plate's (patches, edge springs): with non-proportional
    damping (a g = 0.5 patch) the complex modes need the local deformation these carry. Plain
    truncation at 2.5 x 500 Hz erred by 5e-4 in zeta and frequency; with them < 2e-8. The
    enriched basis is re-diagonalised, so Psi^T M Psi = I and Psi^T K0 Psi = diag(lam_r)."""
    P = Phi[:, lam < (2 * math.pi * f_cut) ** 2]
    K0 = sum(sysm["Kr"]) + sysm["Ks"]
    sysm["chol"] = sla.cho_factor(K0)
    terms = [K for K, u in zip(sysm["Kr"][1:], sysm["used"][1:]) if u]
    terms += [sysm["Ks"]] if sysm["Ks"].any() else []
    if not terms:
        return P, lam[:P.shape[1]]
    M = sysm["M"]
    R = sla.cho_solve(sysm["chol"], np.hstack([K @ P for K in terms]))
    for _ in range(2):                      # M-orthogonal to the kept modes (twice: rounding)
        R -= P @ (P.T @ (M @ R))
    ev, U = sla.eigh(R.T @ M @ R)
    good = ev > 1e-10 * ev.max()            # drop (numerically) dependent directions
    Q = R @ (U[:, good] / np.sqrt(ev[good]))
    for _ in range(2):
        Q -= P @ (P.T @ (M @ Q))
    B = np.hstack([P, Q])
    lam_r, U = sla.eigh(B.T @ K0 @ B, B.T @ M @ B)
    return B @ U, lam_r


def damped_poles(model, sysm, Psi, lam_r):
    """The damped model in the reduced basis Psi (m vectors), in state-space form
        z = [u, v, q_1 .. q_p],  u' = v,
        v' = -(Ka + sum B_r) u - C v + sum B_r q_r + f,   tau_r q_r' = u - q_r,
    Ka = sum_r (1 + j g_r) K_r + K_springs, B_r = (1 + j g_r)(e_r/e_inf_r) K_r (SLS regions:
    then K(s) = Ka + sum B_r s tau_r/(1 + s tau_r), the SLS modulus exactly),
    C = alpha I + beta diag(lam_r). Returns the poles s and the eigenvectors V of the state matrix."""
    m = Psi.shape[1]
    proj = lambda K: Psi.T @ K @ Psi
    Ka = proj(sysm["Ks"]).astype(complex)
    B = []
    for r, K, used in zip(model["regions"], sysm["Kr"], sysm["used"]):
        if not used:
            continue
        Kp = proj(K) * (1 + 1j * r["loss_factor"])
        Ka += Kp
        if r["sls"] is not None:
            sl = r["sls"]
            B.append((Kp * (sl["e"] / sl["e_inf"]), sl["eta"] / sl["e"]))
    C = model["alpha"] * np.eye(m) + model["beta"] * np.diag(lam_r)
    ns = (2 + len(B)) * m
    A = np.zeros((ns, ns), complex)
    A[:m, m:2 * m] = np.eye(m)
    A[m:2 * m, :m] = -(Ka + sum(b for b, _ in B))
    A[m:2 * m, m:2 * m] = -C
    for i, (Br, tau) in enumerate(B):
        o = (2 + i) * m
        A[m:2 * m, o:o + m] = Br
        A[o:o + m, :m] = np.eye(m) / tau
        A[o:o + m, o:o + m] = -np.eye(m) / tau
    s, V = np.linalg.eig(A)
    return s, V


def oscillating(s):
    """The poles of the positive-frequency modes (Im s > 0, Re s <= 0), sorted by Im s; an SLS
    region's relaxation poles (real, Im s ~ rounding) are left out."""
    sel = np.where((s.imag > 1e-7 * np.abs(s)) & (s.real <= 1e-9 * np.abs(s)))[0]
    return sel[np.argsort(s.imag[sel])]


# ----------------------------------------------------------------------------------------------
# Impulse responses
# ----------------------------------------------------------------------------------------------
def frf_model(model, sysm, Psi, lam_r, s, V):
    """Returns H(f): the acceleration FRF (n_f, n_sensors) at the sensors, m/s^2 per N."""
    xe, ye, force = model["exc"]
    Ps = np.array([sysm["point"](x, y) for _, x, y in model["sensors"]])   # (n_sens, n)
    be = sysm["point"](xe, ye) * force
    m = Psi.shape[1]
    # Residues: (sI - A)^-1 = V diag(1/(s - s_n)) V^-1; input enters the v rows, output = u rows.
    rhs = np.zeros(V.shape[0], complex)
    rhs[m:2 * m] = Psi.T @ be
    y = np.linalg.solve(V, rhs)
    R = ((Ps @ Psi) @ V[:m, :]).T * y[:, None]               # (n_poles, n_sens)
    # What the reduced basis misses, as a static flexibility (K0^-1 - Psi lam_r^-1 Psi^T) b.
    r_static = Ps @ (sla.cho_solve(sysm["chol"], be) - Psi @ ((Psi.T @ be) / lam_r))

    def H(f):
        out = np.empty((f.size, Ps.shape[0]), complex)
        for a in range(0, f.size, 2048):                    # chunks bound the memory
            jw = 2j * math.pi * f[a:a + 2048]
            Hu = (1.0 / (jw[:, None] - s[None, :])) @ R + r_static[None, :]
            out[a:a + 2048] = (jw ** 2)[:, None] * Hu
        return out
    return H


def simulate(H, s, fs, seconds):
    """Acceleration impulse responses (n_samples, n_sensors) per unit force impulse."""
    # FFT period: >= 4 x the record and >= the record + the longest T60 of the decaying poles
    # below fs/2, so that what wraps around into the record is < -60 dB. Only poles with
    # Im s >= 0 count: with structural damping (complex K) the Im s < 0 eigenvalues are not
    # the partners of the physical ones (those come from the Hermitian extension of H(f >= 0))
    # and contribute smooth, non-resonant terms for f >= 0.
    band = (s.imag >= -1e-7 * np.abs(s)) & (s.imag < math.pi * fs) & (s.real < 0)
    t60 = (T60_DB / 20 * math.log(10)) / (-s.real[band]).min() if band.any() else MAX_PERIOD_S
    period = min(MAX_PERIOD_S, max(PERIOD_FACTOR * seconds, t60 + seconds))
    if t60 > MAX_PERIOD_S:
        log(f"warning: T60 {t60:.0f} s exceeds the {MAX_PERIOD_S:.0f} s period cap: wrap-around")
    nfft = int(2 * math.ceil(period * fs / 2))
    f = np.arange(nfft // 2 + 1) * fs / nfft
    # Anti-aliasing: half-cosine from 1 at 0.85 fs/2 to 0 at fs/2.
    f1, fn = (1 - TAPER_FRACTION) * fs / 2, fs / 2
    taper = np.where(f <= f1, 1.0, 0.5 * (1 + np.cos(math.pi * np.clip((f - f1) / (fn - f1), 0, 1))))
    # h(t) = int H(f) e^(j 2 pi f t) df ~ fs * irfft (H at f_k = k fs / nfft); by blocks of
    # 16 channels, keeping only the record (memory).
    Hf = H(f)
    Hf *= taper[:, None]
    n_keep = int(round(seconds * fs))
    h = np.empty((n_keep, Hf.shape[1]))
    for c in range(0, Hf.shape[1], 16):
        h[:, c:c + 16] = np.fft.irfft(Hf[:, c:c + 16], n=nfft, axis=0)[:n_keep] * fs
    info = dict(period_s=nfft / fs, nfft=nfft, t60_max_s=t60)
    return h, info


def add_noise(h, snr_db, seed):
    """White Gaussian noise, one sigma for all channels: sigma^2 = mean channel power / 10^(X/10)."""
    sigma = math.sqrt(np.mean(np.mean(h ** 2, axis=0)) / 10 ** (snr_db / 10))
    return h + sigma * np.random.default_rng(seed).standard_normal(h.shape)


def write_set(out, model, h, fs, snr_db, degree, m):
    os.makedirs(out, exist_ok=True)
    wavfile.write(os.path.join(out, "responses.wav"), int(fs), h.astype(np.float32))
    with open(os.path.join(out, "sensors.csv"), "w", encoding="utf-8") as fh:
        fh.write("id,x,y,dir\n")
        fh.writelines(f"{i},{x!r},{y!r},z\n" for i, x, y in model["sensors"])
    xe, ye, force = model["exc"]
    with open(os.path.join(out, "excitation.csv"), "w", encoding="utf-8") as fh:
        fh.write(f"x,y,dir,force\n{xe!r},{ye!r},z,{force!r}\n")
    meta = {"fs": float(fs), "kind": "impulse_response", "quantity": "acceleration",
            "unit": "m/s^2 per N s",
            "generator": f"kirchhoff_sim.py (Kirchhoff plate, Rayleigh-Ritz, C1 piecewise-Legendre "
                         f"basis degree {degree} per direction, {m} vectors in the damped "
                         f"state-space model)"}
    if snr_db is not None:
        meta["snr_db"] = float(snr_db)
    with open(os.path.join(out, "meta.json"), "w", encoding="utf-8") as fh:
        json.dump(meta, fh, indent=2)
        fh.write("\n")


def print_modes(lam, s, fmax):
    f0 = np.sqrt(np.maximum(lam, 0)) / (2 * math.pi)
    print("# undamped natural frequencies (real modes of K0, M; reference moduli)")
    print("mode,frequency_hz")
    for i, f in enumerate(f0[f0 < fmax]):
        print(f"{i + 1},{f:.6f}")
    print("# damped poles s (Im s > 0): damped_frequency_hz = Im s/2pi, |s|/2pi, "
          "damping_ratio = -Re s/|s|")
    print("pole,damped_frequency_hz,abs_s_hz,damping_ratio")
    k = 0
    for i in oscillating(s):
        if s[i].imag / (2 * math.pi) < fmax:
            k += 1
            print(f"{k},{s[i].imag / (2 * math.pi):.6f},{abs(s[i]) / (2 * math.pi):.6f},"
                  f"{-s[i].real / abs(s[i]):.7f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model")
    ap.add_argument("--out", help="recording set directory to write")
    ap.add_argument("--fs", type=int, default=1000, help="sample rate, Hz (integer)")
    ap.add_argument("--seconds", type=float, default=3.0, help="record length, s")
    ap.add_argument("--snr-db", type=float, help="add white noise at this SNR on mean power")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sensors", help="sensors.csv overriding the model's [output] sensors")
    ap.add_argument("--print-modes", type=float, metavar="HZ",
                    help="print undamped frequencies and damped poles below HZ")
    ap.add_argument("--degree", type=int, help="polynomial degree per direction "
                    "(default: from the bending wavenumber at max(fs/2, print-modes), >= 30)")
    ap.add_argument("--cut-factor", type=float, default=2.5, help="damped model uses the real "
                    "modes below this x max(fs/2, print-modes) (default 2.5)")
    a = ap.parse_args(argv)
    t0 = time.time()
    model = load_model(a.model, a.sensors)
    fmax = max(a.fs / 2, a.print_modes or 0.0)
    degree = a.degree or default_degree(model, fmax)
    sysm = build(model, degree)
    lam, Phi = undamped_modes(sysm, a.cut_factor * fmax)
    t1 = time.time()
    Psi, lam_r = reduced_basis(model, sysm, lam, Phi, a.cut_factor * fmax)
    s, V = damped_poles(model, sysm, Psi, lam_r)
    t2 = time.time()
    nk = int((lam < (2 * math.pi * a.cut_factor * fmax) ** 2).sum())
    log(f"basis degree {degree} ({sysm['n']} functions); damped model: {nk} real modes below "
        f"{a.cut_factor * fmax:.0f} Hz + {Psi.shape[1] - nk} residual vectors, {s.size} "
        f"state-space poles; assembly+modes {t1 - t0:.1f} s, reduction+eig {t2 - t1:.1f} s")
    if a.print_modes:
        print_modes(lam, s, a.print_modes)
    if a.out:
        h, info = simulate(frf_model(model, sysm, Psi, lam_r, s, V), s, a.fs, a.seconds)
        if a.snr_db is not None:
            h = add_noise(h, a.snr_db, a.seed)
        write_set(a.out, model, h, a.fs, a.snr_db, degree, Psi.shape[1])
        log(f"FFT period {info['period_s']:.2f} s ({info['nfft']} points; longest T60 below "
            f"fs/2 {info['t60_max_s']:.2f} s); wrote {h.shape[1]} channels x {h.shape[0]} "
            f"samples to {a.out}; total {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
