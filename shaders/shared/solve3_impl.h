// Body of solve3.h, included once per scalar type (no include guard on purpose).
// Needs SOLVE3_REAL, SOLVE3_VEC3 and SOLVE3_MAX_FINITE; see solve3.h for the math.
// Write constants as SOLVE3_REAL(x): a constructor in GLSL, a cast in C++.
#ifdef __cplusplus
#define SOLVE3_INOUT(T) T&
#else
#define SOLVE3_INOUT(T) inout T
#endif

// Normal equations of one element, accumulated row by row.
struct Lsq3Normal {
    SOLVE3_REAL m00; // M = sum w a a^T, upper triangle
    SOLVE3_REAL m01;
    SOLVE3_REAL m02;
    SOLVE3_REAL m11;
    SOLVE3_REAL m12;
    SOLVE3_REAL m22;
    SOLVE3_REAL r0; // r = sum w b a
    SOLVE3_REAL r1;
    SOLVE3_REAL r2;
    uint rows;    // rows with w > 0
    uint invalid; // 1 once a row had a non-finite value or w < 0
};

struct Lsq3Solution {
    SOLVE3_VEC3 g;
    SOLVE3_REAL rcond;
    uint status;
};

// NaN fails every comparison, so this is false for NaN and +-inf.
SHARED_FN bool lsq3_finite(SOLVE3_REAL x) {
    return abs(x) <= SOLVE3_REAL(SOLVE3_MAX_FINITE);
}

SHARED_FN Lsq3Normal lsq3_normal_zero() {
    Lsq3Normal n;
    n.m00 = SOLVE3_REAL(0.0);
    n.m01 = SOLVE3_REAL(0.0);
    n.m02 = SOLVE3_REAL(0.0);
    n.m11 = SOLVE3_REAL(0.0);
    n.m12 = SOLVE3_REAL(0.0);
    n.m22 = SOLVE3_REAL(0.0);
    n.r0 = SOLVE3_REAL(0.0);
    n.r1 = SOLVE3_REAL(0.0);
    n.r2 = SOLVE3_REAL(0.0);
    n.rows = 0u;
    n.invalid = 0u;
    return n;
}

// Adds one row. Rows with w == 0 are skipped (not counted); a non-finite value or
// w < 0 marks the element invalid (its other rows are still counted).
SHARED_FN void lsq3_accumulate(SOLVE3_INOUT(Lsq3Normal) n, SOLVE3_VEC3 a, SOLVE3_REAL b, SOLVE3_REAL w) {
    if (!(lsq3_finite(a.x) && lsq3_finite(a.y) && lsq3_finite(a.z) && lsq3_finite(b) && lsq3_finite(w)) ||
        w < SOLVE3_REAL(0.0)) {
        n.invalid = 1u;
        return;
    }
    if (w == SOLVE3_REAL(0.0)) return;
    SOLVE3_VEC3 wa = w * a;
    n.m00 += wa.x * a.x;
    n.m01 += wa.x * a.y;
    n.m02 += wa.x * a.z;
    n.m11 += wa.y * a.y;
    n.m12 += wa.y * a.z;
    n.m22 += wa.z * a.z;
    n.r0 += wa.x * b;
    n.r1 += wa.y * b;
    n.r2 += wa.z * b;
    n.rows += 1u;
}

// Solves M g = r with the checks described in solve3.h.
SHARED_FN Lsq3Solution lsq3_solve_normal(Lsq3Normal n) {
    Lsq3Solution s;
    s.g = SOLVE3_VEC3(SOLVE3_REAL(0.0));
    s.rcond = SOLVE3_REAL(0.0);
    s.status = kLsq3Ok;
    bool sums_finite = lsq3_finite(n.m00) && lsq3_finite(n.m01) && lsq3_finite(n.m02) && lsq3_finite(n.m11) &&
                       lsq3_finite(n.m12) && lsq3_finite(n.m22) && lsq3_finite(n.r0) && lsq3_finite(n.r1) &&
                       lsq3_finite(n.r2);
    if (n.invalid != 0u || !sums_finite) {
        s.status = kLsq3InvalidInput;
        return s;
    }
    if (n.rows < kLsq3MinRows) {
        s.status = kLsq3TooFewRows;
        return s;
    }
    if (!(n.m00 > SOLVE3_REAL(0.0) && n.m11 > SOLVE3_REAL(0.0) && n.m22 > SOLVE3_REAL(0.0))) {
        s.status = kLsq3IllConditioned; // an unknown no row constrains
        return s;
    }
    // Jacobi scaling: C = S M S, S = diag(1/sqrt(m_ii)), unit diagonal.
    SOLVE3_VEC3 sc = SOLVE3_VEC3(SOLVE3_REAL(1.0) / sqrt(n.m00), SOLVE3_REAL(1.0) / sqrt(n.m11),
                                 SOLVE3_REAL(1.0) / sqrt(n.m22));
    SOLVE3_REAL c01 = n.m01 * sc.x * sc.y;
    SOLVE3_REAL c02 = n.m02 * sc.x * sc.z;
    SOLVE3_REAL c12 = n.m12 * sc.y * sc.z;

    // Symmetric pivoting: the pair (p, q) with the smallest |c_pq| goes first, so the
    // second LDL^T pivot d1 = 1 - c_pq^2 is the largest possible; t is the third index.
    // Then det(C) = d1 d2 with both pivots formed without cancellation beyond the
    // determinant's own conditioning.
    SOLVE3_VEC3 y = sc * SOLVE3_VEC3(n.r0, n.r1, n.r2);
    SOLVE3_REAL cpq = c01;
    SOLVE3_REAL cpt = c02;
    SOLVE3_REAL cqt = c12;
    SOLVE3_VEC3 yp = y; // y in pivot order (p, q, t)
    uint order = 0u;    // 0: (0, 1, 2)   1: (0, 2, 1)   2: (1, 2, 0)
    if (abs(c02) < abs(c01) && abs(c02) <= abs(c12)) {
        cpq = c02;
        cpt = c01;
        cqt = c12;
        yp = SOLVE3_VEC3(y.x, y.z, y.y);
        order = 1u;
    } else if (abs(c12) < abs(c01) && abs(c12) < abs(c02)) {
        cpq = c12;
        cpt = c01;
        cqt = c02;
        yp = SOLVE3_VEC3(y.y, y.z, y.x);
        order = 2u;
    }
    SOLVE3_REAL d1 = (SOLVE3_REAL(1.0) - cpq) * (SOLVE3_REAL(1.0) + cpq);
    SOLVE3_REAL num = cqt - cpq * cpt; // l = num / d1
    SOLVE3_REAL d2 = d1 > SOLVE3_REAL(0.0)
                         ? (SOLVE3_REAL(1.0) - cpt) * (SOLVE3_REAL(1.0) + cpt) - num * num / d1
                         : SOLVE3_REAL(0.0);
    SOLVE3_REAL det = d1 * d2;

    // Reciprocal condition number in the Frobenius norm, from the adjugate (only +, -, *, /
    // and sqrt: no transcendental functions, whose GPU precision is loose; see solve3.h).
    SOLVE3_REAL p1 = c01 * c01 + c02 * c02 + c12 * c12;
    SOLVE3_REAL a00 = (SOLVE3_REAL(1.0) - c12) * (SOLVE3_REAL(1.0) + c12);
    SOLVE3_REAL a11 = (SOLVE3_REAL(1.0) - c02) * (SOLVE3_REAL(1.0) + c02);
    SOLVE3_REAL a22 = (SOLVE3_REAL(1.0) - c01) * (SOLVE3_REAL(1.0) + c01);
    SOLVE3_REAL a01 = c02 * c12 - c01;
    SOLVE3_REAL a02 = c01 * c12 - c02;
    SOLVE3_REAL a12 = c01 * c02 - c12;
    SOLVE3_REAL adj_f = sqrt(a00 * a00 + a11 * a11 + a22 * a22 +
                             SOLVE3_REAL(2.0) * (a01 * a01 + a02 * a02 + a12 * a12));
    SOLVE3_REAL c_f = sqrt(SOLVE3_REAL(3.0) + SOLVE3_REAL(2.0) * p1);
    // 3 / (|C|_F |C^-1|_F) = 3 det / (|C|_F |adj C|_F); det <= 0 (rounding) gives 0.
    s.rcond = adj_f > SOLVE3_REAL(0.0) && det > SOLVE3_REAL(0.0)
                  ? clamp(SOLVE3_REAL(3.0) * det / (c_f * adj_f), SOLVE3_REAL(0.0), SOLVE3_REAL(1.0))
                  : SOLVE3_REAL(0.0);
    if (!(s.rcond >= SOLVE3_REAL(kLsq3MinRcond))) { // also catches NaN
        s.status = kLsq3IllConditioned;
        return s;
    }

    // Forward, diagonal and back substitution with the unit lower L = [1; cpq 1; cpt l 1].
    SOLVE3_REAL l = num / d1;
    SOLVE3_REAL z0 = yp.x;
    SOLVE3_REAL z1 = (yp.y - cpq * z0) / d1;
    SOLVE3_REAL z2 = (yp.z - cpt * z0 - l * (yp.y - cpq * z0)) / d2;
    SOLVE3_REAL x2 = z2;
    SOLVE3_REAL x1 = z1 - l * x2;
    SOLVE3_REAL x0 = z0 - cpq * x1 - cpt * x2;
    SOLVE3_VEC3 x = order == 0u ? SOLVE3_VEC3(x0, x1, x2)
                                : (order == 1u ? SOLVE3_VEC3(x0, x2, x1) : SOLVE3_VEC3(x2, x0, x1));
    SOLVE3_VEC3 g = sc * x;
    if (!(lsq3_finite(g.x) && lsq3_finite(g.y) && lsq3_finite(g.z))) {
        s.status = kLsq3InvalidInput; // r overflowed the solve
        return s;
    }
    s.g = g;
    return s;
}

// One row's term of the residual sum of squares, w (a.g - b)^2 (0 for skipped or invalid rows).
SHARED_FN SOLVE3_REAL lsq3_residual_term(SOLVE3_VEC3 a, SOLVE3_REAL b, SOLVE3_REAL w, SOLVE3_VEC3 g) {
    if (!(lsq3_finite(a.x) && lsq3_finite(a.y) && lsq3_finite(a.z) && lsq3_finite(b) && lsq3_finite(w)) ||
        !(w > SOLVE3_REAL(0.0)))
        return SOLVE3_REAL(0.0);
    SOLVE3_REAL e = dot(a, g) - b;
    return w * e * e;
}

#undef SOLVE3_INOUT
