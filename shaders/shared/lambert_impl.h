// Body of lambert.h, included once per scalar type (no include guard on purpose).
// Needs LAMBERT_REAL, LAMBERT_VEC2, LAMBERT_VEC3. See lambert.h for the method.

// Bilinear footprint of image position (x, y) (pixel centers at i + 0.5): the top-left
// tap (clamped to the image) and the weights of the right and lower taps.
struct LambertTaps {
    int x0;
    int y0;
    int x1;
    int y1;
    LAMBERT_REAL fx;
    LAMBERT_REAL fy;
};

SHARED_FN LambertTaps lambert_taps(LAMBERT_VEC2 pos, int width, int height) {
    LambertTaps t;
    LAMBERT_REAL px = pos.x - LAMBERT_REAL(0.5);
    LAMBERT_REAL py = pos.y - LAMBERT_REAL(0.5);
    LAMBERT_REAL fx0 = floor(px);
    LAMBERT_REAL fy0 = floor(py);
    t.fx = px - fx0;
    t.fy = py - fy0;
    int ix = int(fx0);
    int iy = int(fy0);
    t.x0 = clamp(ix, 0, width - 1);
    t.x1 = clamp(ix + 1, 0, width - 1);
    t.y0 = clamp(iy, 0, height - 1);
    t.y1 = clamp(iy + 1, 0, height - 1);
    return t;
}

SHARED_FN LAMBERT_VEC3 lambert_bilinear(LambertTaps t, LAMBERT_VEC3 c00, LAMBERT_VEC3 c10, LAMBERT_VEC3 c01,
                                        LAMBERT_VEC3 c11) {
    LAMBERT_VEC3 top = c00 + t.fx * (c10 - c00);
    LAMBERT_VEC3 bottom = c01 + t.fx * (c11 - c01);
    return top + t.fy * (bottom - top);
}

// True when a sample with channel-sum ratio q and channel-sum irradiance es stays
// (not a highlight) against the current estimate (lambert.h).
SHARED_FN bool lambert_keep(LAMBERT_REAL q, LAMBERT_REAL es, LAMBERT_REAL est, LAMBERT_REAL tau, LAMBERT_REAL k_sigma) {
    return q <= est * (LAMBERT_REAL(1.0) + tau) + k_sigma * LAMBERT_REAL(1.7320508075688772) / es;
}

// True when a sample lies far BELOW the estimate: a lit particle whose bilinear taps reach
// into a shadow edge (shadows only remove light); dropped like highlights, counted apart.
SHARED_FN bool lambert_low(LAMBERT_REAL q, LAMBERT_REAL es, LAMBERT_REAL est, LAMBERT_REAL tau, LAMBERT_REAL k_sigma) {
    return q < est * (LAMBERT_REAL(1.0) - tau) - k_sigma * LAMBERT_REAL(1.7320508075688772) / es;
}

// True when a view's luminance l is an outlier against the reference ref (lambert.h).
// |ref| keeps the reference itself when it is negative (possible once a known lobe is
// subtracted and over-predicts): otherwise every view, ref included, would be an outlier.
SHARED_FN bool lambert_view_outlier(LAMBERT_REAL l, LAMBERT_REAL ref, LAMBERT_REAL tau, LAMBERT_REAL abs_tol) {
    return abs(l - ref) > tau * abs(ref) + abs_tol;
}

// Angle between unit vectors in degrees, by atan2 (accurate near 0, unlike acos).
SHARED_FN LAMBERT_REAL lambert_angle_deg(LAMBERT_VEC3 a, LAMBERT_VEC3 b) {
    return atan(length(cross(a, b)), dot(a, b)) * LAMBERT_REAL(57.29577951308232);
}

// Octahedral decoding of a unit normal (lambert.h surface maps): e in [-1, 1]^2 as
// unpackSnorm2x16 returns it.
SHARED_FN LAMBERT_VEC3 lambert_oct_decode(LAMBERT_VEC2 e) {
    LAMBERT_VEC3 n = LAMBERT_VEC3(e.x, e.y, LAMBERT_REAL(1.0) - abs(e.x) - abs(e.y));
    LAMBERT_REAL t = max(-n.z, LAMBERT_REAL(0.0));
    n.x += n.x >= LAMBERT_REAL(0.0) ? -t : t;
    n.y += n.y >= LAMBERT_REAL(0.0) ? -t : t;
    return normalize(n);
}

// Per-tap irradiance (lambert.h): the gain that brings a tap whose pixel shows surface point
// x with unit normal nt to the particle's irradiance factor e_particle = n.u / d^2, for the
// light at `light`. Negative when the tap's surface gets n.u below min_cos (the sample is
// then dropped as grazing: its gain would amplify the pixel's noise without bound).
SHARED_FN LAMBERT_REAL lambert_tap_gain(LAMBERT_VEC3 x, LAMBERT_VEC3 nt, LAMBERT_VEC3 light, LAMBERT_REAL e_particle,
                                        LAMBERT_REAL min_cos) {
    LAMBERT_VEC3 L = light - x;
    LAMBERT_REAL d2 = dot(L, L);
    LAMBERT_REAL c = dot(nt, L) / sqrt(d2);
    if (!(c >= min_cos)) return LAMBERT_REAL(-1.0);
    return e_particle * d2 / c;
}
