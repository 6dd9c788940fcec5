// Body of image_metrics_shared.h, included once per scalar type METRICS_REAL
// (no include guard on purpose). Constants are written METRICS_REAL(x): a
// constructor in GLSL, a cast in C++.

// Unnormalised 1D Gaussian tap at integer offset d (the window is normalised by the
// caller over the taps that fall inside the image).
SHARED_FN METRICS_REAL ssim_gauss_tap(int d) {
    METRICS_REAL s = METRICS_REAL(kSsimSigma);
    return exp(-METRICS_REAL(d * d) / (METRICS_REAL(2.0f) * s * s));
}

// Linear luminance (ITU-R BT.709 primaries); a one-channel image is its own luminance.
SHARED_FN METRICS_REAL metrics_luma(METRICS_REAL r, METRICS_REAL g, METRICS_REAL b, uint color_channels) {
    return color_channels == 1u ? r : METRICS_REAL(kLumaR) * r + METRICS_REAL(kLumaG) * g + METRICS_REAL(kLumaB) * b;
}

// SSIM index from the windowed moments (Wang et al. 2004, eq. 13; sigma^2 = E[Y^2] - mu^2).
SHARED_FN METRICS_REAL ssim_index(METRICS_REAL mu_a, METRICS_REAL mu_b, METRICS_REAL aa, METRICS_REAL bb,
                                  METRICS_REAL ab, METRICS_REAL c1, METRICS_REAL c2) {
    METRICS_REAL var_a = aa - mu_a * mu_a;
    METRICS_REAL var_b = bb - mu_b * mu_b;
    METRICS_REAL cov = ab - mu_a * mu_b;
    return ((METRICS_REAL(2.0f) * mu_a * mu_b + c1) * (METRICS_REAL(2.0f) * cov + c2)) /
           ((mu_a * mu_a + mu_b * mu_b + c1) * (var_a + var_b + c2));
}

// Squared Hausdorff point distance between pixel p of X and pixel q of Y, given the
// pixel offset (dx, dy) and the colour distance squared (see image_metrics.h):
//     d^2 = delta^2 (dx^2 + dy^2) + sum_c (X_pc - Y_qc)^2
SHARED_FN METRICS_REAL hausdorff_d2(int dx, int dy, METRICS_REAL delta, METRICS_REAL color_d2) {
    return delta * delta * METRICS_REAL(dx * dx + dy * dy) + color_d2;
}
