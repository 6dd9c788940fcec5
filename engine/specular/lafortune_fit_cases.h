#pragma once
// The stiff-case suite of the Lafortune fit, in one place for the test
// (tests/specular/lafortune_fit_test.cpp) and `specula bench fit`: synthetic samples from
// known lobes, sampled like a capture rig, and how each case is judged.
//
//   for (const LafortuneFitCase& c : lafortune_fit_cases()) {
//       LafortuneCaseResult r = run_lafortune_case(c, /*with_plain=*/true);
//       r.robust_pass, r.robust_verdict, r.plain_verdict ...
//   }
#include "specular/lafortune_fit.h"

#include <cstdint>
#include <string>
#include <vector>

namespace specula {

/// How the directions of a case are drawn.
enum class CaseSampling {
    /// A capture rig: view polar angle up to 75 deg; 80% of lights within 60 deg of the
    /// view, 20% near the lobe's peak direction for that view (perturbed by 0.01..20 deg,
    /// log-uniform), as the highlights a real capture photographs.
    Rig,
    /// As Rig, but both directions between 70 and 88 deg from the normal.
    Grazing,
    /// As Rig, keeping only samples below `tail_fraction` of the lobe's peak.
    TailOnly,
    /// As Rig, without the samples near the peak: only lights within 60 deg of the view,
    /// so a narrow lobe is hit by chance alone.
    RigNoHighlights,
};

/// What an honest fit must do on a case.
enum class CaseExpect {
    Recover,                  ///< converged, within the tolerances
    /// either, but never converged and wrong; constrained (the fallback) counts as
    /// underdetermined, and on a mirror-lobe truth (Cx = -Cz) must be within the tolerances
    RecoverOrUnderdetermined,
    Underdetermined,
    NoSpecularEnergy,
};

struct LafortuneFitCase {
    std::string name;
    double cx = -1.0, cz = 1.0, n = 10.0; ///< the truth
    std::uint64_t samples = 20000;
    CaseSampling sampling = CaseSampling::Rig;
    double tail_fraction = 0.1;  ///< TailOnly: samples below this fraction of the peak
    double noise = 0.0;          ///< Gaussian noise, sigma relative to the largest true value of the case
    double noise_abs = 0.0;      ///< Gaussian noise, absolute sigma
    double clip = 0.0;           ///< > 0: values capped at this fraction of the largest true value
    bool tell_noise = false;     ///< pass the noise sigma to the fit
    double tol_c = 0.02;         ///< relative tolerance on Cx and Cz
    double tol_n = 0.05;         ///< relative tolerance on N
    CaseExpect expect = CaseExpect::Recover;
    bool compare_plain = true;   ///< also run the thesis's plain recipe
    bool long_running = false;   ///< the 10-million-sample case: its own test
    std::uint64_t seed = 1;
    std::string note;
};

/// All cases: N in {1, 3, 10, 100, 1000, 10000}; the thesis's table 5.2 lobes (noise-free
/// and 1% noise); Cz < 0; off-specular; retro-reflective; grazing only; no highlight
/// samples; tail only (the peak never seen); 0/1/5% noise; clipped; 10 and 3 samples;
/// noise only; 10 million samples (long_running).
[[nodiscard]] std::vector<LafortuneFitCase> lafortune_fit_cases();

/// The samples of a case (deterministic in its seed). All three channels hold the same value.
[[nodiscard]] std::vector<LafortuneSample> make_case_samples(const LafortuneFitCase& c);

/// The options a case's fit runs with (method robust or plain).
[[nodiscard]] LafortuneFitOptions case_options(const LafortuneFitCase& c, LafortuneFitMethod method,
                                               const std::vector<LafortuneSample>& samples);

/// "recovered", "wrong: ..." (converged to another lobe), or the status; never hides NaN.
[[nodiscard]] std::string case_verdict(const LafortuneFitCase& c, const LafortuneChannelFit& fit);
/// Whether a converged fit is within the case's tolerances.
[[nodiscard]] bool case_recovered(const LafortuneFitCase& c, const LafortuneChannelFit& fit);
/// Whether the robust fit did what the case expects (see CaseExpect).
[[nodiscard]] bool case_pass(const LafortuneFitCase& c, const LafortuneChannelFit& fit);

struct LafortuneCaseResult {
    LafortuneChannelFit robust;
    LafortuneChannelFit plain; ///< only when run with the plain recipe
    bool plain_run = false;
    bool robust_pass = false;
    std::string robust_verdict, plain_verdict;
    double sample_seconds = 0.0;
};

[[nodiscard]] LafortuneCaseResult run_lafortune_case(const LafortuneFitCase& c, bool with_plain);

/// One line per case: case, truth, recovered, iterations, time, status, the plain recipe's outcome.
[[nodiscard]] std::string lafortune_case_table_header();
[[nodiscard]] std::string lafortune_case_table_row(const LafortuneFitCase& c, const LafortuneCaseResult& r);

} // namespace specula
