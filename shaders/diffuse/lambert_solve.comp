#version 450
// lambert_solve, pair step: one invocation per (particle, view) pair of a particle chunk,
// after the gather step (lambert_gather.comp) wrote one record per frame of the view. Counts
// the rejected samples, finds the highlights (lower median of the channel-sum ratios by
// selection in the scratch buffer, then iterated refits) and solves albedo or photometric
// mode (method and thresholds: shared/lambert.h; reference: engine/diffuse/lambert_solve_cpu.cpp,
// which follows this step for step). Any number of frames per view: nothing is held per frame
// in the invocation; each pass recomputes a sample from its record and its light.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/lambert.h"
#include "shared/solve3.h"

layout(local_size_x_id = 0) in;

struct ParticleGpu {
    vec4 position;
    vec4 normal;
    vec2 bary;
    uint triangle;
    uint texel;
};

layout(std430, set = 0, binding = 0) readonly buffer Particles { ParticleGpu particles[]; };
layout(std430, set = 0, binding = 1) readonly buffer Views { LambertViewGpu views[]; };    // every view
layout(std430, set = 0, binding = 2) readonly buffer Frames { LambertFrameGpu frames[]; }; // their train frames
layout(std430, set = 0, binding = 3) readonly buffer Records { vec4 records[]; };
layout(std430, set = 0, binding = 4) buffer Scratch { float scratch[]; }; // one float per record
layout(std430, set = 0, binding = 5) readonly buffer Keys { LambertSolveKey keys[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Results { LambertPairResult results[]; };

layout(push_constant) uniform PushBlock { LambertPairPush pc; }; // shared header: one definition for GLSL and C++

// One usable sample of the pair (shared/lambert.h): c with the known specular light
// subtracted, E = I k_d n.u / d^2, I, a = k_d u / d^2, es = E_r + E_g + E_b, q = sum(c) / es.
struct PairSample {
    vec3 c;
    vec3 e;
    vec3 i;
    vec3 a;
    float es;
    float q;
};

PairSample pair_sample(vec4 rec, LambertFrameGpu fr, vec3 P, vec3 n) {
    PairSample s;
    vec3 L = fr.light.xyz - P;
    float d2 = dot(L, L);
    vec3 u = L / sqrt(d2);
    float kd = rec.w;
    s.c = rec.xyz;
    s.i = fr.intensity.xyz;
    s.e = fr.intensity.xyz * (dot(n, u) / d2) * kd;
    s.a = (u / d2) * kd;
    s.es = s.e.x + s.e.y + s.e.z;
    s.q = (s.c.x + s.c.y + s.c.z) / s.es;
    return s;
}

// Kept (not a highlight, not a shadow edge) against the estimate est.
bool pair_keep(PairSample s, float est) {
    return lambert_keep(s.q, s.es, est, pc.tau, pc.k_sigma) && !lambert_low(s.q, s.es, est, pc.tau, pc.k_sigma);
}

// The element of rank k (0-based, ascending) of scratch[first, first + n): Hoare selection,
// in place. The value equals the reference's std::nth_element.
float select_rank(uint first, uint n, uint k) {
    int lo = int(first);
    int hi = int(first + n) - 1;
    int target = int(first + k);
    while (lo < hi) {
        float pivot = scratch[(lo + hi) / 2];
        int i = lo;
        int j = hi;
        while (i <= j) {
            while (scratch[i] < pivot) ++i;
            while (scratch[j] > pivot) --j;
            if (i <= j) {
                float tmp = scratch[i];
                scratch[i] = scratch[j];
                scratch[j] = tmp;
                ++i;
                --j;
            }
        }
        if (target <= j) hi = j;
        else if (target >= i) lo = i;
        else break;
    }
    return scratch[target];
}

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    LambertSolveKey key = keys[e];
    ParticleGpu part = particles[key.particle];
    LambertViewGpu view = views[key.view];
    vec3 P = part.position.xyz;
    vec3 n = part.normal.xyz;
    vec3 vdir = normalize(view.center.xyz - P);

    LambertPairResult r;
    r.view = key.view;
    r.albedo = vec4(0.0, 0.0, 0.0, dot(n, vdir));
    r.normal = vec4(n, 0.0);
    r.status = 0u;
    r.shadow = 0u;
    r.clipped = 0u;
    r.missing = 0u;
    r.grazing = 0u;
    r.frames = view.frame_count;
    r.pad0 = 0u;
    r.pad1 = 0u;

    // Rejections, and the usable samples' ratios q into the scratch buffer.
    uint ns = 0u;
    for (uint k = 0u; k < view.frame_count; ++k) {
        vec4 rec = records[key.record + k];
        if (rec.w > 0.0) {
            scratch[key.record + ns] = pair_sample(rec, frames[view.frame_first + k], P, n).q;
            ++ns;
            continue;
        }
        uint reason = uint(-rec.w);
        if (reason == kLambertRecordShadow) ++r.shadow;
        else if (reason == kLambertRecordClipped) ++r.clipped;
        else if (reason == kLambertRecordMissing) ++r.missing;
        else ++r.grazing;
    }

    // Highlights: lower median of q, then iterated refits (shared/lambert.h). The kept set of
    // an iteration depends only on the estimate it used, so it is recomputed, not stored.
    float est = ns > 0u ? select_rank(key.record, ns, (ns - 1u) / 2u) : 0.0;
    bool fitted = false; // an iteration ran: the kept set is pair_keep(s, est_kept), else every sample
    float est_kept = est;
    for (uint it = 0u; it < pc.iterations && ns > 0u; ++it) {
        bool changed = false;
        float num = 0.0, den = 0.0;
        for (uint k = 0u; k < view.frame_count; ++k) {
            vec4 rec = records[key.record + k];
            if (!(rec.w > 0.0)) continue;
            PairSample s = pair_sample(rec, frames[view.frame_first + k], P, n);
            bool keep = pair_keep(s, est);
            bool before = fitted ? pair_keep(s, est_kept) : true;
            changed = changed || keep != before;
            if (keep) {
                num += s.q * s.es * s.es;
                den += s.es * s.es;
            }
        }
        fitted = true;
        est_kept = est;
        if (den > 0.0) est = num / den;
        if (!changed && it > 0u) break;
    }
    uint kept = 0u, low = 0u;
    for (uint k = 0u; k < view.frame_count; ++k) {
        vec4 rec = records[key.record + k];
        if (!(rec.w > 0.0)) continue;
        PairSample s = pair_sample(rec, frames[view.frame_first + k], P, n);
        if (!fitted || pair_keep(s, est_kept)) ++kept;
        else if (s.q < est) ++low;
    }
    r.used = kept;
    r.low = low;
    r.highlight = ns - kept - low;

    if (kept > 0u) {
        r.status |= kLambertPairHasSample;
        vec3 rho = vec3(0.0);
        bool solved = false;
        if (pc.mode == kLambertModePhotometric) {
            if (kept >= kLsq3MinRows) {
                Lsq3Normal n0 = lsq3_normal_zero();
                Lsq3Normal n1 = lsq3_normal_zero();
                Lsq3Normal n2 = lsq3_normal_zero();
                for (uint k = 0u; k < view.frame_count; ++k) {
                    vec4 rec = records[key.record + k];
                    if (!(rec.w > 0.0)) continue;
                    PairSample s = pair_sample(rec, frames[view.frame_first + k], P, n);
                    if (fitted && !pair_keep(s, est_kept)) continue;
                    lsq3_accumulate(n0, s.i.x * s.a, s.c.x, 1.0);
                    lsq3_accumulate(n1, s.i.y * s.a, s.c.y, 1.0);
                    lsq3_accumulate(n2, s.i.z * s.a, s.c.z, 1.0);
                }
                Lsq3Solution s0 = lsq3_solve_normal(n0);
                Lsq3Solution s1 = lsq3_solve_normal(n1);
                Lsq3Solution s2 = lsq3_solve_normal(n2);
                bool ok = s0.status == kLsq3Ok && s0.rcond >= pc.min_rcond && s1.status == kLsq3Ok &&
                          s1.rcond >= pc.min_rcond && s2.status == kLsq3Ok && s2.rcond >= pc.min_rcond;
                vec3 sum = s0.g + s1.g + s2.g;
                float len = length(sum);
                if (ok && len > 0.0 && dot(sum, n) > 0.0) {
                    vec3 nr = sum / len;
                    rho = kPi * vec3(length(s0.g), length(s1.g), length(s2.g));
                    r.normal = vec4(nr, lambert_angle_deg(nr, n));
                    r.status |= kLambertPairPhotometric;
                    solved = true;
                }
            }
            if (!solved) r.status |= kLambertPairFallback;
        }
        if (!solved) {
            vec3 num = vec3(0.0), den = vec3(0.0);
            for (uint k = 0u; k < view.frame_count; ++k) {
                vec4 rec = records[key.record + k];
                if (!(rec.w > 0.0)) continue;
                PairSample s = pair_sample(rec, frames[view.frame_first + k], P, n);
                if (fitted && !pair_keep(s, est_kept)) continue;
                num += s.c * s.e;
                den += s.e * s.e;
            }
            rho.x = den.x > 0.0 ? kPi * num.x / den.x : 0.0;
            rho.y = den.y > 0.0 ? kPi * num.y / den.y : 0.0;
            rho.z = den.z > 0.0 ? kPi * num.z / den.z : 0.0;
        }
        r.albedo.xyz = rho;
    }
    results[key.slot] = r;
}
