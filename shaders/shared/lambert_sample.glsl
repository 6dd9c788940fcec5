// GLSL only: one sample of a (particle, view, frame) triple as the Lambert solve and the
// residual samples read it (shared/lambert.h): the 4 bilinear taps, their flags, their
// finiteness, saturation, and, when the view has a surface map, each tap's irradiance gain.
// The C++ reference is lambert_read_sample in engine/diffuse/lambert_solve_detail.h.
// Include after shared/lambert.h and after declaring `pixels` (uvec4[]: rgb float bits and
// the PixelFlag bits, or a surface map's 4 words).
#ifndef SPECULA_SHARED_LAMBERT_SAMPLE_GLSL
#define SPECULA_SHARED_LAMBERT_SAMPLE_GLSL

const uint kLambertSampleOk = 0u;
const uint kLambertSampleMissing = 1u; // a tap flagged missing / outside the mask, not finite, or showing no surface
const uint kLambertSampleClipped = 2u; // a tap at or above saturation, or flagged clipped
const uint kLambertSampleGrazing = 3u; // a tap's surface gets n.u below min_cos

struct LambertSample {
    vec3 c;      // bilinear mix of the (gained) taps
    uint status; // kLambertSample*
};

bool lambert_finite3(vec3 v) {
    return abs(v.x) <= 3.0e38 && abs(v.y) <= 3.0e38 && abs(v.z) <= 3.0e38;
}

// Tap i of 4 (00, 10, 01, 11) as a pixel index of a w-wide image.
uint lambert_tap_index(LambertTaps t, int w, uint i) {
    int x = (i & 1u) == 0u ? t.x0 : t.x1;
    int y = (i & 2u) == 0u ? t.y0 : t.y1;
    return uint(y * w + x);
}

// frame_base: the frame's first pixel; sat: its saturation; surface_base: the view's surface
// map (kLambertNoSurface: none, no gains); light: the light's position; e_particle: n.u / d^2
// at the particle.
LambertSample lambert_read_sample(LambertTaps t, int w, uint frame_base, float sat, uint surface_base, vec3 light,
                                  float e_particle, float min_cos) {
    LambertSample s;
    s.c = vec3(0.0);
    vec3 c[4];
    uint fl = 0u;
    bool finite = true;
    vec3 mx = vec3(-3.0e38);
    for (uint i = 0u; i < 4u; ++i) {
        uvec4 p = pixels[frame_base + lambert_tap_index(t, w, i)];
        c[i] = uintBitsToFloat(p.xyz);
        fl |= p.w;
        finite = finite && lambert_finite3(c[i]);
        mx = max(mx, c[i]);
    }
    if ((fl & (kLambertPixMissing | kLambertPixOutside)) != 0u || !finite) {
        s.status = kLambertSampleMissing;
        return s;
    }
    if ((fl & kLambertPixClipped) != 0u || mx.x >= sat || mx.y >= sat || mx.z >= sat) {
        s.status = kLambertSampleClipped;
        return s;
    }
    if (surface_base != kLambertNoSurface) {
        for (uint i = 0u; i < 4u; ++i) {
            uvec4 q = pixels[surface_base + lambert_tap_index(t, w, i)];
            if (q.w == kLambertNoHit) {
                s.status = kLambertSampleMissing;
                return s;
            }
            float g = lambert_tap_gain(uintBitsToFloat(q.xyz), lambert_oct_decode(unpackSnorm2x16(q.w)), light, e_particle,
                                       min_cos);
            if (g < 0.0) {
                s.status = kLambertSampleGrazing;
                return s;
            }
            c[i] *= g;
        }
    }
    s.c = lambert_bilinear(t, c[0], c[1], c[2], c[3]);
    s.status = kLambertSampleOk;
    return s;
}

#endif
