#pragma once
// Errors inside the engine are exceptions; tools turn them into exit codes.
// Library code never exits the process.
#include <filesystem>
#include <stdexcept>
#include <string>

namespace specula {

/// Base of every error the engine throws on purpose.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Bad command-line use: tools print it and exit with status 2.
class UsageError : public Error {
public:
    using Error::Error;
};

/// Input that breaks a contract (capture format, mesh, image): names the file
/// and the field, so a user can find and fix it. what() = "FILE: FIELD: MESSAGE".
class InputError : public Error {
public:
    InputError(std::filesystem::path file, std::string field, const std::string& message);
    [[nodiscard]] const std::filesystem::path& file() const noexcept { return m_file; }
    [[nodiscard]] const std::string& field() const noexcept { return m_field; }
    [[nodiscard]] const std::string& message() const noexcept { return m_message; }

private:
    std::filesystem::path m_file;
    std::string m_field;
    std::string m_message;
};

/// A numerical result that cannot be trusted (the caller decides whether that is fatal).
class NumericalError : public Error {
public:
    using Error::Error;
};

} // namespace specula
