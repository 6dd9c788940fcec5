// Body of gshd.h, included once per scalar type (no include guard on purpose).
// Needs GSHD_REAL, GSHD_VEC2, GSHD_VEC3; see gshd.h for the math and its sources.
// Constants are written GSHD_REAL(x): a constructor in GLSL, a cast in C++.

// ---- hemispherical octahedral map -------------------------------------------------

// Upper-hemisphere direction (any length; z < 0 is treated as z = 0) -> e in [-1, 1]^2.
SHARED_FN GSHD_VEC2 hemi_oct_encode(GSHD_VEC3 w) {
    GSHD_REAL z = max(w.z, GSHD_REAL(0.0));
    GSHD_REAL l1 = abs(w.x) + abs(w.y) + z;
    GSHD_REAL px = l1 > GSHD_REAL(0.0) ? w.x / l1 : GSHD_REAL(0.0);
    GSHD_REAL py = l1 > GSHD_REAL(0.0) ? w.y / l1 : GSHD_REAL(0.0);
    return GSHD_VEC2(px + py, px - py);
}

// e in [-1, 1]^2 -> unit upper-hemisphere direction (|p.x| + |p.y| = max(|e.x|, |e.y|) <= 1).
SHARED_FN GSHD_VEC3 hemi_oct_decode(GSHD_VEC2 e) {
    GSHD_REAL px = (e.x + e.y) * GSHD_REAL(0.5);
    GSHD_REAL py = (e.x - e.y) * GSHD_REAL(0.5);
    GSHD_REAL z = max(GSHD_REAL(1.0) - abs(px) - abs(py), GSHD_REAL(0.0));
    return normalize(GSHD_VEC3(px, py, z));
}

// Centre of grid cell `index` (= row * res + column) in map coordinates.
SHARED_FN GSHD_VEC2 gshd_grid_center(uint index, uint res) {
    uint i = index % res;
    uint j = index / res;
    GSHD_REAL scale = GSHD_REAL(2.0) / GSHD_REAL(res);
    return GSHD_VEC2((GSHD_REAL(i) + GSHD_REAL(0.5)) * scale - GSHD_REAL(1.0),
                     (GSHD_REAL(j) + GSHD_REAL(0.5)) * scale - GSHD_REAL(1.0));
}

// Direction through the centre of grid cell `index`.
SHARED_FN GSHD_VEC3 gshd_grid_dir(uint index, uint res) {
    return hemi_oct_decode(gshd_grid_center(index, res));
}

// Bilinear lookup of direction w on a res x res grid (res >= 2): the four cells and
// weights; value = (1-fx)(1-fy) v[i00] + fx (1-fy) v[i10] + (1-fx) fy v[i01] + fx fy v[i11].
struct GshdBilinear {
    uint i00;
    uint i10;
    uint i01;
    uint i11;
    GSHD_REAL fx;
    GSHD_REAL fy;
};

SHARED_FN GshdBilinear gshd_grid_bilinear(GSHD_VEC3 w, uint res) {
    GSHD_VEC2 e = hemi_oct_encode(w);
    GSHD_REAL r = GSHD_REAL(res);
    // Continuous cell coordinates: cell centres at integers, clamped to the edge centres.
    GSHD_REAL x = clamp((e.x + GSHD_REAL(1.0)) * GSHD_REAL(0.5) * r - GSHD_REAL(0.5), GSHD_REAL(0.0), r - GSHD_REAL(1.0));
    GSHD_REAL y = clamp((e.y + GSHD_REAL(1.0)) * GSHD_REAL(0.5) * r - GSHD_REAL(0.5), GSHD_REAL(0.0), r - GSHD_REAL(1.0));
    uint x0 = min(uint(floor(x)), res - 2u);
    uint y0 = min(uint(floor(y)), res - 2u);
    GshdBilinear b;
    b.i00 = y0 * res + x0;
    b.i10 = b.i00 + 1u;
    b.i01 = b.i00 + res;
    b.i11 = b.i01 + 1u;
    b.fx = x - GSHD_REAL(x0);
    b.fy = y - GSHD_REAL(y0);
    return b;
}

SHARED_FN GSHD_VEC3 gshd_bilinear_mix(GshdBilinear b, GSHD_VEC3 v00, GSHD_VEC3 v10, GSHD_VEC3 v01, GSHD_VEC3 v11) {
    GSHD_VEC3 bottom = v00 + (v10 - v00) * b.fx;
    GSHD_VEC3 top = v01 + (v11 - v01) * b.fx;
    return bottom + (top - bottom) * b.fy;
}

// ---- GSHD reparametrization (thesis eq. A.5) --------------------------------------

struct GshdCoords {
    GSHD_VEC3 h; // half vector (tangent frame)
    GSHD_VEC3 d; // u in the frame (t', s', h): (u.t', u.s', u.h)
};

struct GshdPair {
    GSHD_VEC3 u; // light
    GSHD_VEC3 v; // view
};

// t' = norm(t - (t.h) h) with t = +x; |t - (t.h) h|^2 = 1 - h.x^2. When h is (nearly)
// along +-x (only at the horizon) the helper becomes +y (our fallback; eq. A.5 leaves it open).
SHARED_FN GSHD_VEC3 gshd_tangent(GSHD_VEC3 h) {
    GSHD_VEC3 t = GSHD_VEC3(1.0, 0.0, 0.0) - h.x * h;
    GSHD_REAL len2 = dot(t, t);
    if (len2 < GSHD_REAL(1.0e-8)) {
        t = GSHD_VEC3(0.0, 1.0, 0.0) - h.y * h;
        len2 = dot(t, t);
    }
    return t * inversesqrt(len2);
}

// (u, v) -> (h, d). u = -v (only possible on the horizon) gets h = n.
SHARED_FN GshdCoords gshd_from_uv(GSHD_VEC3 u, GSHD_VEC3 v) {
    GSHD_VEC3 sum = u + v;
    GSHD_REAL len2 = dot(sum, sum);
    GshdCoords c;
    c.h = len2 > GSHD_REAL(1.0e-12) ? sum * inversesqrt(len2) : GSHD_VEC3(0.0, 0.0, 1.0);
    GSHD_VEC3 t = gshd_tangent(c.h);
    GSHD_VEC3 s = cross(c.h, t);
    c.d = GSHD_VEC3(dot(u, t), dot(u, s), dot(u, c.h));
    return c;
}

// (h, d) -> (u, v): u = d.x t' + d.y s' + d.z h, v = 2 (u.h) h - u (the mirror of u about h).
SHARED_FN GshdPair gshd_to_uv(GSHD_VEC3 h, GSHD_VEC3 d) {
    GSHD_VEC3 t = gshd_tangent(h);
    GSHD_VEC3 s = cross(h, t);
    GshdPair p;
    p.u = d.x * t + d.y * s + d.z * h;
    p.v = (GSHD_REAL(2.0) * d.z) * h - p.u;
    return p;
}

// ---- mirrored GSHD (gshd.h part 4) ------------------------------------------------

// r(u) = (-ux, -uy, uz): the mirror direction of u about the normal (its own inverse).
SHARED_FN GSHD_VEC3 gshd_mirror(GSHD_VEC3 u) {
    return GSHD_VEC3(-u.x, -u.y, u.z);
}

// (u, v) -> (h, d) in parametrization `param` (kGshdPlain: gshd_from_uv; kGshdMirrored: of (r(u), v)).
SHARED_FN GshdCoords gshd_from_uv_param(GSHD_VEC3 u, GSHD_VEC3 v, uint param) {
    return gshd_from_uv(param == kGshdMirrored ? gshd_mirror(u) : u, v);
}

// (h, d) -> (u, v), the inverse of gshd_from_uv_param.
SHARED_FN GshdPair gshd_to_uv_param(GSHD_VEC3 h, GSHD_VEC3 d, uint param) {
    GshdPair p = gshd_to_uv(h, d);
    if (param == kGshdMirrored) p.u = gshd_mirror(p.u);
    return p;
}

// ---- warped GSHD (gshd.h part 5) --------------------------------------------------

// w(u) = norm(s ux, s uy, k uz) with warp = (s, k), s = +-1, k > 0.
SHARED_FN GSHD_VEC3 gshd_warp(GSHD_VEC3 u, GSHD_VEC2 warp) {
    return normalize(GSHD_VEC3(warp.x * u.x, warp.x * u.y, warp.y * u.z));
}

// Its inverse: norm(s u'x, s u'y, u'z / k).
SHARED_FN GSHD_VEC3 gshd_unwarp(GSHD_VEC3 w, GSHD_VEC2 warp) {
    return normalize(GSHD_VEC3(warp.x * w.x, warp.x * w.y, w.z / warp.y));
}

// (u, v) -> (h, d) in any parametrization: kGshdWarped takes the GSHD of (w(u), v), the
// others are gshd_from_uv_param (warp unused).
SHARED_FN GshdCoords gshd_from_uv_warped(GSHD_VEC3 u, GSHD_VEC3 v, uint param, GSHD_VEC2 warp) {
    if (param == kGshdWarped) return gshd_from_uv(gshd_warp(u, warp), v);
    return gshd_from_uv_param(u, v, param);
}

// (h, d) -> (u, v), the inverse of gshd_from_uv_warped.
SHARED_FN GshdPair gshd_to_uv_warped(GSHD_VEC3 h, GSHD_VEC3 d, uint param, GSHD_VEC2 warp) {
    if (param != kGshdWarped) return gshd_to_uv_param(h, d, param);
    GshdPair p = gshd_to_uv(h, d);
    p.u = gshd_unwarp(p.u, warp);
    return p;
}

// A sampled lobe value as F stores it: flushed below kGshdMinValue, clamped at kGshdMaxValue.
SHARED_FN GSHD_VEC3 gshd_clamp_value(GSHD_VEC3 f) {
    GSHD_VEC3 r = min(f, GSHD_VEC3(kGshdMaxValue));
    if (r.x < GSHD_REAL(kGshdMinValue)) r.x = GSHD_REAL(0.0);
    if (r.y < GSHD_REAL(kGshdMinValue)) r.y = GSHD_REAL(0.0);
    if (r.z < GSHD_REAL(kGshdMinValue)) r.z = GSHD_REAL(0.0);
    return r;
}

// ---- cube-map texels (thesis Algorithm 2, Vulkan face convention) -----------------

// Whether texel direction `dir` (cube_texel_dir, major axis +-1) takes the grid's value: the
// upper hemisphere (z > 0) and the horizon gutter, the row of texels just below the horizon
// on the side faces (z > -1.5 / res: the centres at -1/res for an even res; for an odd one
// the row at z = 0 is the last one a lookup at z >= 0 reaches, and -2/res is left out). The
// gutter holds the grid at the horizon point of its azimuth (hemi_oct_encode takes z < 0 as
// 0), so a bilinear lookup at a grazing h or d does not blend in the lower hemisphere's zeros
// (ours; the thesis's Algorithm 2 zeroes the whole lower hemisphere, which halves G and H at
// the horizon). Every other lower-hemisphere texel is 0.
SHARED_FN bool cube_texel_kept(GSHD_VEC3 dir, uint res) {
    return dir.z > GSHD_REAL(-1.5) / GSHD_REAL(res);
}

// Direction (not normalized) from the cube's centre through the centre of texel (col, row)
// of `face` (0..5 = +X, -X, +Y, -Y, +Z, -Z) of a res x res face: the inverse of the
// Vulkan spec's face selection table (sc, tc, ma).
SHARED_FN GSHD_VEC3 cube_texel_dir(uint face, uint col, uint row, uint res) {
    GSHD_REAL sc = (GSHD_REAL(2u * col + 1u)) / GSHD_REAL(res) - GSHD_REAL(1.0);
    GSHD_REAL tc = (GSHD_REAL(2u * row + 1u)) / GSHD_REAL(res) - GSHD_REAL(1.0);
    if (face == 0u) return GSHD_VEC3(1.0, -tc, -sc);
    if (face == 1u) return GSHD_VEC3(-1.0, -tc, sc);
    if (face == 2u) return GSHD_VEC3(sc, 1.0, tc);
    if (face == 3u) return GSHD_VEC3(sc, -1.0, -tc);
    if (face == 4u) return GSHD_VEC3(sc, -tc, 1.0);
    return GSHD_VEC3(-sc, -tc, -1.0);
}
