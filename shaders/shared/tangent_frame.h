// Tangent (TBN) frame of a surface point, thesis appendix B: the normal is +Z,
// model +Y is the helper, +X = normalize(Y x Z), then +Y = Z x X. When the
// normal is (nearly) parallel to model +Y the helper becomes model +Z (our
// fallback; the thesis leaves this case open). Rows of the returned basis map
// world directions to local ones: local = vec3(dot(w, x), dot(w, y), dot(w, z)).
#ifndef SPECULA_SHARED_TANGENT_FRAME_H
#define SPECULA_SHARED_TANGENT_FRAME_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

// |n.y| above this uses the fallback helper.
const float kTangentHelperSwitch = 0.9999f;

SHARED_FN vec3 tangent_frame_x(vec3 n) {
    vec3 helper = abs(n.y) > kTangentHelperSwitch ? vec3(0.0f, 0.0f, 1.0f) : vec3(0.0f, 1.0f, 0.0f);
    return normalize(cross(helper, n));
}

// World direction w expressed in the frame of unit normal n.
SHARED_FN vec3 to_tangent_frame(vec3 n, vec3 w) {
    vec3 x = tangent_frame_x(n);
    vec3 y = cross(n, x);
    return vec3(dot(w, x), dot(w, y), dot(w, n));
}

SPECULA_SHARED_END
#endif
