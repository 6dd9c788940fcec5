// Default resolutions from the lobe's width.
//
// Width of the lobe. Near its peak a Lafortune lobe behaves like cos^N of the angle theta
// between v and the (off-)specular direction, and cos^N theta ~ exp(-N theta^2 / 2), which
// falls to 1/e at the angular half-width w = sqrt(2 / N). (Along h the peak is narrower,
// about w/2 in the plane of incidence, since turning h by a turns v by 2a; the rule below
// with k = 2 cells per w thus puts about one cell per half-width of G's peak. The sweep,
// bench/factorization_sweep.cpp, shows the error of the thesis's lobes is at
// its separability floor from R = 16 on, so the rule is not made finer.)
//
// Cell size of the hemispherical octahedral grid (shared/gshd.h) at the pole, where a
// specular G peaks: a step of 2/R in e.x moves p by (1/R, 1/R), i.e. sqrt(2)/R radians.
// k cells per half-width: sqrt(2)/R = w / k  =>  R = k sqrt(2) / w = k sqrt(N).
//
// Along d the lobe varies with u.h only (at h = n: f = ((Cx + Cz) dz^2 - Cx)^N), whose
// logarithmic rate in dz^2 is about N |Cx + Cz| / max(|Cx|, |Cz|) =: N_d: a mirror-like
// lobe (Cx = -Cz) is flat along d, an off-specular one (|Cx| != |Cz|) is not. The same
// rule with N_d gives R_d.
//
// The mirrored parametrization (shared/gshd.h part 4) swaps the two: F_mirrored of a lobe at
// (h, d) is the lobe at (r(u), v) with (u, v) = gshd_to_uv(h, d), and slicing as above,
//   at d = pole (u = v = h):  plain  f = ((Cz - Cx) hz^2 + Cx)^N        (the peak: rule h)
//                             mirror f = ((Cx + Cz) hz^2 - Cx)^N        (rule d's N_d)
//   at h = n (v = r(u)):      plain  f = ((Cx + Cz) dz^2 - Cx)^N        (rule d's N_d)
//                             mirror f = ((Cz - Cx) dz^2 + Cx)^N        (the peak: rule h)
// so the mirrored grids take the plain rule's values with h and d exchanged: the d grid
// resolves the peak (a Phong lobe, Cx = -Cz, is a function of d alone there), the h grid the
// off-specular variation.
//
// The peak's axis is finer in the mirrored parametrization (kMirroredPeakCellsPerHalfWidth =
// 16 against 2). The plain GSHD's error at the presets' lobes is its separability floor from
// R = 16 on; the mirrored one has no such floor (the can's K = 3: 1.8% on the grid), so the
// bilinear interpolation of the peak between cells is what is left, and rendered highlights,
// which saturate, show mostly its tails, where interpolating an exponential fall-off between
// cells overestimates it. Measured (specula evaluate, factorized vs analytic masked PSNR, 30
// frames per split, h grid 16; tools/refactor_bundle): the can (N = 11) d 16 /
// 32 / 64: train -2.4 / -0.65 / -0.33 dB, test -0.26 / -0.07 / -0.04 dB; cologne (N = 18.5)
// d 16 / 32 / 64 / 96 / 128: test -19.7 / -9.8 / -1.4 / -0.17 / -0.18 dB. 16 cells per
// half-width gives the can 53 and cologne 69: F (3 R_h^2 R_d^2 floats) grows ~20 times.
//
// Cube faces: a texel at a face centre spans (pi/2)/R_cube radians; matching a grid cell
// (sqrt(2)/R) gives R_cube = R pi / (2 sqrt 2) ~ 1.11 R.
#include "factorization/resolution.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace specula::factorization {

namespace {

double sane_exponent(float n) { return std::isfinite(n) && n > 1.0f ? static_cast<double>(n) : 1.0; }

uint32_t res_for(double exponent, uint32_t lo, uint32_t hi, double cells_per_half_width) {
    const double r = std::ceil(cells_per_half_width * std::sqrt(std::max(exponent, 1.0)));
    return static_cast<uint32_t>(std::clamp(r, static_cast<double>(lo), static_cast<double>(hi)));
}

} // namespace

uint32_t cube_res_for_grid(uint32_t grid_res) {
    const double pi = 3.14159265358979323846;
    const auto r = static_cast<uint32_t>(std::ceil(grid_res * pi / (2.0 * std::sqrt(2.0))));
    return std::max<uint32_t>(8, (r + 7u) / 8u * 8u);
}

namespace {

// The warped parametrization (shared/gshd.h part 5): F = max(0, +-(2 dz^2 - 1))^N per channel, a
// function of d alone, so G is flat and R_h is the least; R_d resolves the peak of width
// sqrt(2/N) with kWarpedPeakCellsPerHalfWidth cells (doubled when the peak is at d's horizon,
// Cz < 0). Measured (specula evaluate, factorized vs analytic train masked PSNR, 12 frames,
// h 16, one term): vase (N = 20) d 72 / 96 / 128: -1.74 / -0.73 / -0.24 dB; cologne (N = 18.5)
// d 70 / 96 / 128: -1.04 / -0.46 / -0.21 dB; woodenpot (N = 10, Cz < 0) d 51 / 96 / 128:
// -2.67 / -0.81 / -0.35 dB. 28 cells give the vase 127 and cologne 122.
FactorizationResolution warped_resolution(const LafortuneRgb& lobe) {
    double n_max = 1.0;
    bool horizon = false;
    for (int c = 0; c < 3; ++c) {
        n_max = std::max(n_max, sane_exponent(lobe.n[c]));
        horizon = horizon || lobe.cz[c] < 0.0f;
    }
    const double cells = kWarpedPeakCellsPerHalfWidth * (horizon ? 2.0 : 1.0);
    FactorizationResolution r;
    r.grid_h = kMinGridRes;
    r.grid_d = res_for(n_max, kMinGridRes, kMaxGridResH, cells);
    r.cube_g = cube_res_for_grid(r.grid_h);
    r.cube_h = cube_res_for_grid(r.grid_d);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "warped parametrization: F is rank 1 per channel, G flat -> h grid %u; lobe half-width sqrt(2/N) = "
                  "%.3f rad (N = %.4g) -> d grid %u (%.0f cells per half-width%s, clamped [%u, %u]); cube faces %u (G) "
                  "and %u (H): texel <= grid cell",
                  r.grid_h, std::sqrt(2.0 / n_max), n_max, r.grid_d, cells,
                  horizon ? ", doubled: Cz < 0 puts the peak at d's horizon" : "", kMinGridRes, kMaxGridResH, r.cube_g,
                  r.cube_h);
    r.reason = buf;
    return r;
}

// The coated family (shared/coated.h), plain or mirrored GSHD. In the plain GSHD h is the half
// vector, so the GGX peak D(n.h) lies along h (width about alpha radians), and d = (u in the
// frame of h) carries the Fresnel factor F(u.h) = F(d.z) and the masking over 4 (n.u)(n.v),
// which vary fastest towards d's horizon (grazing pairs, seen by lights far from the camera); in
// the mirrored GSHD the two swap, as for a lobe. Both axes want cells: the peak ~ 1/alpha of them
// (a near-camera light looks at it), the grazing axis more for a rougher lobe (its energy reaches
// grazing pairs), and F (3 R_h^2 R_d^2 floats) allows R_h R_d <= kMaxGridProduct. So the grazing
// axis gets ceil(kCoatedGrazingCellsPerAlpha alpha) cells in [32, 64] and the peak axis the rest
// of the budget (at most kMaxGridResH). Measured (masked PSNR of the factorized render against the
// analytic one, preset meshes can, cologne, vase, woodenpot, knot at 128 px, 4 + 2 views of the
// spread rig and of the thesis's ring rig, eta 1.5, plain GSHD, no weight; worst near-camera frame
// / worst far-light frame / lowest mean over a preset's frames, in dB; before the coated
// factorized term was cut at the view's horizon, render/terms.glsl, which only raises them):
//   alpha 0.05: 128 x 24 41.4 / 28.1 / 52.0;   96 x 32 40.8 / 40.2 / 53.7;   64 x 48 36.1 / 42.3 / 50.6
//   alpha 0.12:  96 x 32 37.7 / 35.6 / 50.3;   64 x 48 43.3 / 43.3 / 56.5;   48 x 64 39.3 / 45.1 / 53.8
//   alpha 0.25 (weight q = 2, factorization.h): 32 x 64 45.5 / 44.2 / 56.0;  48 x 64 49.1 / 44.3 / 57.4
//   alpha 0.4  (q = 2): 16 x 64 48.5 / 39.3 / 56.6;  32 x 64 56.8 / 39.3 / 58.9
// The rule gives 96 x 32, 64 x 48, 48 x 64 and 48 x 64.
FactorizationResolution coated_resolution(const CoatedParams& coated, FactorParam param) {
    const bool mirrored = param == FactorParam::Mirrored;
    const double alpha = std::isfinite(coated.alpha) && coated.alpha > 0.0f ? static_cast<double>(coated.alpha) : 1.0;
    const double g = std::ceil(kCoatedGrazingCellsPerAlpha * alpha);
    const auto grazing = static_cast<uint32_t>(
        std::clamp(g, static_cast<double>(kCoatedMinGrazingRes), static_cast<double>(kCoatedMaxGrazingRes)));
    const uint32_t peak = std::min(kMaxGridResH, kMaxGridProduct / grazing);
    FactorizationResolution out;
    out.grid_h = mirrored ? grazing : peak;
    out.grid_d = mirrored ? peak : grazing;
    out.cube_g = cube_res_for_grid(out.grid_h);
    out.cube_h = cube_res_for_grid(out.grid_d);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "coated family%s: alpha = %.3g -> grazing axis %s grid %u (%.0f alpha, clamped [%u, %u]); the GGX peak's "
                  "%s grid %u (the rest of R_h R_d <= %u, at most %u); cube faces %u (G) and %u (H): texel <= grid cell",
                  mirrored ? ", mirrored parametrization (the peak along d)" : " (the peak along h)", alpha,
                  mirrored ? "h" : "d", grazing, kCoatedGrazingCellsPerAlpha, kCoatedMinGrazingRes, kCoatedMaxGrazingRes,
                  mirrored ? "d" : "h", peak, kMaxGridProduct, kMaxGridResH, out.cube_g, out.cube_h);
    out.reason = buf;
    return out;
}

} // namespace

FactorizationResolution default_resolution(const SpecularModel& model, FactorParam param) {
    if (const auto* coated = std::get_if<CoatedParams>(&model)) return coated_resolution(*coated, param);
    const LafortuneRgb& lobe = std::get<LafortuneRgb>(model);
    if (param == FactorParam::Warped) return warped_resolution(lobe);
    const bool mirrored = param == FactorParam::Mirrored;
    double n_max = 1.0;
    double n_d = 1.0;
    for (int c = 0; c < 3; ++c) {
        const double n = sane_exponent(lobe.n[c]);
        n_max = std::max(n_max, n);
        const double ax = std::abs(static_cast<double>(lobe.cx[c]));
        const double az = std::abs(static_cast<double>(lobe.cz[c]));
        const double big = std::max(ax, az);
        if (big > 0.0 && std::isfinite(big))
            n_d = std::max(n_d, n * std::abs(static_cast<double>(lobe.cx[c]) + lobe.cz[c]) / big);
    }
    // peak: the axis that resolves the lobe's width; other: the off-specular variation.
    const double peak_cells = mirrored ? kMirroredPeakCellsPerHalfWidth : kCellsPerHalfWidth;
    uint32_t peak = res_for(n_max, kMinGridRes, kMaxGridResH, peak_cells);
    uint32_t other = res_for(n_d, kMinGridRes, kMaxGridResD, kCellsPerHalfWidth);
    bool limited = false;
    while (peak * other > kMaxGridProduct) {
        limited = true;
        if (other > kMinGridRes) --other; else --peak;
    }
    FactorizationResolution r;
    r.grid_h = mirrored ? other : peak;
    r.grid_d = mirrored ? peak : other;
    r.cube_g = cube_res_for_grid(r.grid_h);
    r.cube_h = cube_res_for_grid(r.grid_d);
    const char* peak_axis = mirrored ? "d" : "h";
    const char* other_axis = mirrored ? "h" : "d";
    char buf[640];
    std::snprintf(buf, sizeof buf,
                  "%slobe half-width sqrt(2/N) = %.3f rad (N = %.4g) -> %s grid %u (%.0f cells per half-width, clamped "
                  "[%u, %u]); variation along %s N|Cx+Cz|/max|C| = %.3g -> %s grid %u (clamped [%u, %u])%s; cube faces "
                  "%u (G) and %u (H): texel <= grid cell",
                  mirrored ? "mirrored parametrization, the axes swapped: " : "", std::sqrt(2.0 / n_max), n_max, peak_axis,
                  peak, peak_cells, kMinGridRes, kMaxGridResH, other_axis, n_d, other_axis, other, kMinGridRes,
                  kMaxGridResD, limited ? "; reduced so that F (3 R_h^2 R_d^2 floats) fits one 128 MiB storage binding" : "",
                  r.cube_g, r.cube_h);
    r.reason = buf;
    return r;
}

} // namespace specula::factorization
