#pragma once
// Runs f and returns the InputError it throws, so a test can check file() and field();
// anything else thrown, or nothing thrown, fails the test.
#include "core/error.h"

#include <gtest/gtest.h>

#include <exception>

namespace specula::test {

template <class F>
InputError expect_input_error(F&& f) {
    try {
        f();
    } catch (const InputError& e) {
        return e;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "expected an InputError, got: " << e.what();
        return InputError("", "", "");
    }
    ADD_FAILURE() << "expected an InputError, nothing was thrown";
    return InputError("", "", "");
}

} // namespace specula::test
