#pragma once
// Internal pieces of the Lambert solve's reference, for the tests (one pair, one combine).
#include "diffuse/lambert_solve.h"

namespace specula::detail {

/// The pair step of one (particle, view) in double.
[[nodiscard]] shared::LambertPairResult lambert_pair_cpu(const LambertInputs& in, const LambertOptions& o,
                                                         std::uint32_t particle, std::uint32_t view);
/// The combine step of one particle over its pairs (in view order).
[[nodiscard]] LambertParticleResult lambert_combine_cpu(std::span<const shared::LambertPairResult> pairs,
                                                        const LambertOptions& o, const Particle& particle);

} // namespace specula::detail
