// Body of tangent_frame.h, included once per scalar type (no include guard on purpose).
// Needs TANGENT_REAL and TANGENT_VEC3. See tangent_frame.h.

SHARED_FN TANGENT_VEC3 tangent_frame_x(TANGENT_VEC3 n) {
    TANGENT_VEC3 helper = abs(n.y) > TANGENT_REAL(kTangentHelperSwitch)
                              ? TANGENT_VEC3(TANGENT_REAL(0.0), TANGENT_REAL(0.0), TANGENT_REAL(1.0))
                              : TANGENT_VEC3(TANGENT_REAL(0.0), TANGENT_REAL(1.0), TANGENT_REAL(0.0));
    return normalize(cross(helper, n));
}

// World direction w expressed in the frame of unit normal n.
SHARED_FN TANGENT_VEC3 to_tangent_frame(TANGENT_VEC3 n, TANGENT_VEC3 w) {
    TANGENT_VEC3 x = tangent_frame_x(n);
    TANGENT_VEC3 y = cross(n, x);
    return TANGENT_VEC3(dot(w, x), dot(w, y), dot(w, n));
}
