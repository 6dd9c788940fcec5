#include "core/error.h"

namespace specula {

namespace {
std::string format_input_error(const std::filesystem::path& file, const std::string& field,
                               const std::string& message) {
    std::string s = file.string();
    if (!field.empty()) s += ": " + field;
    return s + ": " + message;
}
} // namespace

InputError::InputError(std::filesystem::path file, std::string field, const std::string& message)
    : Error(format_input_error(file, field, message)), m_file(std::move(file)), m_field(std::move(field)),
      m_message(message) {}

} // namespace specula
