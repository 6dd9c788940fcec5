// Body of material.h, included once per scalar type (no include guard on purpose).
// Needs MATERIAL_REAL and MATERIAL_VEC3; the parameters are read from the float struct.

// The specular BRDF f_s per channel.
SHARED_FN MATERIAL_VEC3 material_specular(MaterialGpu m, MATERIAL_REAL ci, MATERIAL_REAL co, MATERIAL_REAL cuv) {
    if (m.family.x == kMaterialCoated) {
        MATERIAL_REAL s = coated_specular(ci, co, cuv, MATERIAL_REAL(m.a.y), MATERIAL_REAL(m.a.x));
        return MATERIAL_VEC3(m.b.x, m.b.y, m.b.z) * s;
    }
    if (m.family.x == kMaterialGltfCore)
        return MATERIAL_VEC3(core_clearcoat_dim(co, MATERIAL_REAL(m.b.x)) *
                                 core_specular(ci, co, cuv, MATERIAL_REAL(m.a.x), MATERIAL_REAL(m.a.y), MATERIAL_REAL(m.a.z)) +
                             core_clearcoat_specular(ci, co, cuv, MATERIAL_REAL(m.b.x), MATERIAL_REAL(m.b.y)));
    // Lafortune, from the isotropic products (shared/lafortune.h lafortune_eval_ab).
    MATERIAL_REAL a = cuv - ci * co;
    MATERIAL_REAL b = ci * co;
    return MATERIAL_VEC3(lafortune_eval_ab(MATERIAL_REAL(m.a.x), MATERIAL_REAL(m.b.x), MATERIAL_REAL(m.c.x), a, b),
                         lafortune_eval_ab(MATERIAL_REAL(m.a.y), MATERIAL_REAL(m.b.y), MATERIAL_REAL(m.c.y), a, b),
                         lafortune_eval_ab(MATERIAL_REAL(m.a.z), MATERIAL_REAL(m.b.z), MATERIAL_REAL(m.c.z), a, b));
}

// The diffuse term's angular factor k_d: f_d = (rho / pi) k_d (1 for the Lambertian base of the lafortune family).
SHARED_FN MATERIAL_REAL material_diffuse_factor(MaterialGpu m, MATERIAL_REAL ci, MATERIAL_REAL co) {
    if (m.family.x == kMaterialCoated) return coated_diffuse_factor(ci, co, MATERIAL_REAL(m.a.x));
    return MATERIAL_REAL(1.0);
}

// k_d for any family, from u.v too (the glTF core family's Fresnel depends on v.h).
SHARED_FN MATERIAL_REAL material_diffuse_factor_uv(MaterialGpu m, MATERIAL_REAL ci, MATERIAL_REAL co, MATERIAL_REAL cuv) {
    if (m.family.x == kMaterialGltfCore)
        return core_clearcoat_dim(co, MATERIAL_REAL(m.b.x)) *
               core_diffuse_factor(ci, co, cuv, MATERIAL_REAL(m.a.y), MATERIAL_REAL(m.a.z), MATERIAL_REAL(m.a.w));
    return material_diffuse_factor(m, ci, co);
}
