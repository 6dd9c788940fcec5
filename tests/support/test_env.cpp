// The test environment, set before main() in every test binary (specula_add_test links
// this object). ctest's ENVIRONMENT property does not survive gtest_discover_tests as a
// list (only its first element arrives), so the defaults are set here instead; a
// variable already in the environment wins, so a developer can still point the tests
// at another driver or turn validation off.
#include <cstdlib>

namespace {

struct TestEnvironment {
    TestEnvironment() {
#ifdef SPECULA_TEST_LVP_ICD
        setenv("VK_DRIVER_FILES", SPECULA_TEST_LVP_ICD, 0);   // lavapipe, the CPU Vulkan driver
        setenv("VK_ICD_FILENAMES", SPECULA_TEST_LVP_ICD, 0);  // the same, for older loaders
#endif
        setenv("LP_NUM_THREADS", "2", 0);
        setenv("SPECULA_VALIDATION", "1", 0);                 // Khronos validation on in every context
        setenv("SPECULA_SOURCE_DIR", SPECULA_TEST_SOURCE_DIR, 0);
    }
};

const TestEnvironment g_environment;

} // namespace
