// Kautz-McCool factorization, shared math (thesis appendix A; Kautz and McCool 1999,
// "Interactive rendering with arbitrary BRDFs using separable approximations"):
//
// 1. The Gram-Schmidt half/difference reparametrization (GSHD, thesis eq. A.5), local
//    tangent frame (t, s, n) = (x, y, z):
//        h  = norm(u + v)
//        t' = norm(t - (t.h) h)          (fallback t = y when h is along +-x: at the horizon)
//        s' = h x t'
//        d  = (u.t', u.s', u.h)          u in the right-handed frame (t', s', h)
//    The thesis writes d = [u.h, u.s', u.t']: the same vector with its axes permuted; we
//    keep u.h (the polar coordinate, = cos of half the angle between u and v, always >= 0)
//    as d.z so that h and d are both directions of the upper hemisphere (z >= 0) and share
//    one hemisphere map. Inverse: u = d.x t' + d.y s' + d.z h,  v = 2 (u.h) h - u.
//
// 2. The hemisphere grid: the hemispherical octahedral map (Engelhardt and Dachsbacher
//    2008, "Octahedron environment maps"; the hemisphere variant of Cigolle et al. 2014,
//    "A survey of efficient representations for independent unit vectors", JCGT 3(2)):
//        p = w.xy / (|w.x| + |w.y| + w.z),   e = (p.x + p.y, p.x - p.y) in [-1, 1]^2
//    Why this map: a direction -> grid lookup needs only abs, add and one divide (no
//    atan/acos, which Vulkan lets a GPU compute with 2^-11 absolute error), it has no
//    pole (theta/phi wastes a whole row on theta = 0, where a specular lobe's G peaks),
//    its cells stay within a factor 5 in solid angle (largest / smallest 4.9 at R = 64,
//    measured by the tests), and the square's boundary is exactly the horizon.
//    A grid of resolution R has R x R cells; cell (i, j) (column i along e.x, row j along
//    e.y, index j R + i) is centred at e = (2 (i + 0.5) / R - 1, 2 (j + 0.5) / R - 1).
//    Values are interpolated bilinearly between cell centres and clamped at the edge
//    (the behaviour of a VkSampler with LINEAR filtering and CLAMP_TO_EDGE on an R x R
//    image), so a grid can also be bound as a 2D texture.
//
// 3. Cube-map texels (thesis Algorithm 2) in Vulkan's face order and orientation
//    (Vulkan spec, "Cube Map Face Selection and Transformations"): faces +X, -X, +Y, -Y,
//    +Z, -Z; texel (col, row) of a face of size R has (s, t) = ((col + 0.5) / R,
//    (row + 0.5) / R), so an array [face][row][col][rgb] uploads directly as a cube image.
//
// 4. The mirrored GSHD (ours; not in the thesis): the GSHD of the pair (r(u), v) with
//        r(u) = (-ux, -uy, uz) = 2 (u.n) n - u      the mirror direction of u about the normal
//    (the reflection about n, i.e. a rotation by pi about it: u.z, so the hemisphere tests,
//    are unchanged, and r(r(u)) = u). Why: the Lafortune lobe (shared/lafortune.h) is
//        f(u, v) = (Cx (ux vx + uy vy) + Cz uz vz)^N = (-Cx (r(u)x vx + r(u)y vy) + Cz r(u)z vz)^N,
//    so with Cx = -Cz (a Phong lobe about the mirror direction) f = Cz^N (r(u).v)^N, and
//    r(u).v = cos(2 theta_d) is a function of the GSHD difference vector of (r(u), v) alone:
//    F is exactly rank 1 in this parametrization and far from it in the plain one (the
//    demo can's lobe, Cx = -0.90, Cz = 0.76, keeps 16% matrix RMS with 4 plain terms).
//    Conversely a retro-reflective lobe (Cx = +Cz) is rank 1 in the plain GSHD, u.v being a
//    function of d. Coordinates: gshd_from_uv_param(u, v, kGshdMirrored) =
//    gshd_from_uv(r(u), v); inverse gshd_to_uv_param: (u', v) = gshd_to_uv(h, d), u = r(u').
//    kGshdPlain is the thesis's parametrization; the factorization picks one per lobe
//    (engine/factorization/factorization.h) and the bundle records which.
//
// 5. The warped GSHD (ours; not in the thesis): the GSHD of the pair (w(u), v) with
//        w(u) = norm(s ux, s uy, k uz)       s = +-1, k > 0: the warp (s, k)
//    and F tabulating the lobe divided by its radial factor |C u|^N (C = diag(Cx, Cx, Cz);
//    shared/lafortune.h lafortune_radial). Why: with s = sign(Cx Cz) and k = |Cz| / |Cx|,
//        C u = sign(Cz) |C u| w(u),   so   f(u, v) = |C u|^N max(0, sign(Cz) w(u).v)^N
//    and w(u).v = cos(2 theta_d) = 2 dz^2 - 1 is a function of the GSHD difference vector of
//    (w(u), v) alone: f / |C u|^N (lafortune_normalized, in [0, 1]) is exactly rank 1 for
//    every Lafortune lobe, off-specular (|Cx| != |Cz|) and Cz < 0 ones included, where parts 1
//    and 4 are rank 1 only for Cx = +-Cz. The mirrored GSHD is the warp (-1, 1) without the
//    radial factor. Each channel has its own k (the lobe's warp is (s, k_r, k_g, k_b), s shared;
//    engine/material/factor_param.h warp_for_lobe): channel c's F, and its lookups when rendering,
//    use the pair in the warp (s, k_c), so every channel is exactly rank 1 (one shared k left
//    1.0-1.3% matrix error on the cologne and vase lobes, whose channels' k differ by 3%, which
//    further terms did not remove). The renderer computes the coordinates once per channel and
//    multiplies the looked-up terms by lafortune_radial per channel (render/terms.glsl): the
//    one part of the lobe evaluated in closed form, a function of the light's elevation only.
//    Coordinates: gshd_from_uv_warped(u, v, kGshdWarped, warp) = gshd_from_uv(w(u), v); the
//    inverse maps u' back by w^-1(u') = norm(s u'x, s u'y, u'z / k) (w keeps the sign of u.z,
//    so the hemisphere tests are unchanged). For kGshdPlain and kGshdMirrored these functions
//    are gshd_from_uv_param / gshd_to_uv_param and the warp is ignored.
//
// Rendering (pipeline.md section 7) looks G and H up as
//     GshdCoords c = gshd_from_uv_param(u, v, param);       // u, v in the tangent frame
//     f ~ texture(cube_g, c.h).rgb * texture(cube_h, c.d).rgb
// (or, from the grids: gshd_grid_bilinear(c.h, R_h) and gshd_grid_bilinear(c.d, R_d)).
//
// The body is in gshd_impl.h, written over GSHD_REAL / GSHD_VEC2 / GSHD_VEC3 and
// instantiated for float (GLSL and C++: namespace specula::shared) and, in C++ only, for
// double (namespace specula::shared::f64: the CPU reference).
#ifndef SPECULA_SHARED_GSHD_H
#define SPECULA_SHARED_GSHD_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

// F entries whose (u, v) is not a pair of upper-hemisphere directions (some (h, d) pairs
// of two upper-hemisphere directions give u or v below the horizon): outside the BRDF's
// domain. The decomposition skips them; they are never looked up when rendering.
// "Below the horizon" is u.z or v.z <= kGshdMinCos (not 0): pairs exactly on the horizon
// (there are many on the grids, by symmetry) would otherwise fall on either side by rounding.
const float kGshdInvalid = -1.0f;
const float kGshdMinCos = 1.0e-5f;
// F values are clamped at kGshdMaxValue (a lobe whose height |C|^N overflows float stays
// finite) and flushed to 0 below kGshdMinValue (far above float's smallest normal 1.2e-38,
// so a GPU that flushes denormals and the double reference agree on which rows of F are
// zero; a lobe value below 1e-30 is zero for rendering).
const float kGshdMaxValue = 3.0e38f;
const float kGshdMinValue = 1.0e-30f;
// Summation block of the decomposition (both sides): sums of up to 64 terms are added
// to the total, so the float sum of K terms has a relative error <= (64 + K / 64) eps.
const uint kGshdSumBlock = 64u;
const uint kCubeFaces = 6u;
// The parametrizations of parts 4 and 5 (engine/material/factor_param.h FactorParam has these values).
const uint kGshdPlain = 0u;
const uint kGshdMirrored = 1u;
const uint kGshdWarped = 2u;

#define GSHD_REAL float
#define GSHD_VEC2 vec2
#define GSHD_VEC3 vec3
#include "shared/gshd_impl.h"
#undef GSHD_REAL
#undef GSHD_VEC2
#undef GSHD_VEC3

SPECULA_SHARED_END

#ifdef __cplusplus
namespace specula::shared::f64 {
using namespace glm;
#define GSHD_REAL double
#define GSHD_VEC2 dvec2
#define GSHD_VEC3 dvec3
#include "shared/gshd_impl.h"
#undef GSHD_REAL
#undef GSHD_VEC2
#undef GSHD_VEC3
} // namespace specula::shared::f64
#endif

#endif
