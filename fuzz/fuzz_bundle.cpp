// libFuzzer target: a bundle (.glb with or without the SPECULA_lafortune extension) through
// read_bundle, which specula render, evaluate and specula-view call first. A refusal is an
// InputError; anything else that escapes is a finding.
#include "core/error.h"
#include "export/bundle.h"
#include "fuzz_input.h"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto path = specula::fuzz::write_input(data, size, "object.glb");
    try {
        (void)specula::read_bundle(path);
    } catch (const specula::InputError&) {
    }
    return 0;
}
