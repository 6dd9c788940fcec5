#include "material/material.h"

namespace specula {

std::optional<MaterialFamily> material_family_from_string(const std::string& s) noexcept {
    for (std::size_t i = 0; i < kMaterialFamilyCount; ++i) {
        const auto f = static_cast<MaterialFamily>(i);
        if (s == to_string(f)) return f;
    }
    return std::nullopt;
}

bool is_zero(const SpecularModel& m) noexcept {
    return std::visit([](const auto& model) { return model.is_zero(); }, m);
}

} // namespace specula
