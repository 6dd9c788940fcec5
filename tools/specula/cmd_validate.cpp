// `specula validate CAPTURE_DIR`: loads a capture as reconstruction would
// (capture.json, mesh, images and masks) and prints a summary. Any refusal
// propagates as an InputError (main prints "error: FILE: FIELD: MESSAGE", exit 1).
#include "capture/capture.h"
#include "commands.h"

#include <cstdio>
#include <memory>
#include <string>

namespace specula::cli {

namespace {
struct ValidateOptions {
    std::string capture;
    bool no_images = false;
    int threads = 2;
};
} // namespace

void add_validate_command(CLI::App& app) {
    auto opts = std::make_shared<ValidateOptions>();
    CLI::App* cmd = app.add_subcommand("validate", "Check a capture against the capture format and summarize it");
    cmd->add_option("capture", opts->capture, "Capture folder, or its capture.json")->required();
    cmd->add_flag("--no-images", opts->no_images, "Read image headers only (sizes checked, pixels not decoded)");
    cmd->add_option("--threads", opts->threads, "Image decoding threads")->check(CLI::Range(1, 256));
    cmd->callback([opts] {
        CaptureLoadOptions load;
        load.load_images = !opts->no_images;
        load.threads = opts->threads;
        const Capture capture = load_capture(opts->capture, load);
        std::fputs(summarize(capture).c_str(), stdout);
    });
}

} // namespace specula::cli
