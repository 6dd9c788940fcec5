// Dual-use prelude: this header and the shared/*.h headers that include it are
// compiled both by glslang (GLSL 450) and by the C++ compiler (with GLM), so
// the math that both sides need is written once (style.md, habit 4).
//   GLSL: #extension GL_GOOGLE_include_directive : require
//         #include "shared/prelude.h"
//   C++:  #include "shared/prelude.h"   (functions live in specula::shared)
// Write shared code with float literals ("0.0f"), GLSL built-ins that GLM also
// has (dot, cross, normalize, pow, max, abs, clamp, sqrt), and SHARED_FN.
#ifndef SPECULA_SHARED_PRELUDE_H
#define SPECULA_SHARED_PRELUDE_H

#ifdef __cplusplus
#include <glm/glm.hpp>
#include <cstdint>
#define SHARED_FN inline
#define SPECULA_SHARED_BEGIN \
    namespace specula::shared { \
    using namespace glm;
#define SPECULA_SHARED_END }
#else
#define SHARED_FN
#define SPECULA_SHARED_BEGIN
#define SPECULA_SHARED_END
#endif

// pi, the project's one definition: a float constant in GLSL, a double in C++ (specula::kPi,
// visible in specula::shared and its f64 twin too).
#ifdef __cplusplus
namespace specula {
inline constexpr double kPi = 3.14159265358979323846;
}
#else
const float kPi = 3.14159265358979323846;
#endif

#endif
