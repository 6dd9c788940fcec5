// `specula import photometric` (capture/import_photometric.h): a synthetic photometric-stereo
// dataset (photometric_dataset.h) imports into a capture of format 1.1 whose lights are the
// directions and irradiances it was rendered with, whose images are the dataset's; every bad
// input is refused naming the file and the line or field, and leaves no output folder.
#include "capture/import_photometric.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/file_util.h"
#include "expect_error.h"
#include "photometric_dataset.h"
#include "test_dirs.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>

namespace specula {
namespace {

namespace fs = std::filesystem;

/// The dataset in `dir/data`, its mesh in `dir/scan.glb`; the capture goes to `dir/capture`.
struct ImportFixture {
    test::TempDir dir{"import"};
    fs::path data = dir / "data";
    fs::path mesh = dir / "scan.glb";
    fs::path out = dir / "capture";
    test::PhotometricTruth truth;
    PhotometricImportOptions options;

    explicit ImportFixture(const test::PhotometricDatasetSpec& spec = {}) {
        truth = test::write_photometric_dataset(data, mesh, spec);
        options.mesh = mesh;
        options.fl_x = truth.intrinsics.fl_x;
        options.pose = truth.pose;
        options.irradiance_scale = truth.irradiance_scale;
    }

    PhotometricImportResult run() const { return import_photometric(data, out, options); }

    /// Replaces line `line` (1-based) of a dataset text file.
    void edit_line(const std::string& file, int line, const std::string& text) const {
        const std::string old = read_text_file(data / file);
        std::string result;
        int n = 1;
        std::size_t start = 0;
        while (start < old.size()) {
            const std::size_t end = old.find('\n', start);
            result += (n == line ? text : old.substr(start, end - start)) + "\n";
            start = end + 1;
            ++n;
        }
        write_text_file(data / file, result);
    }
};

// The imported capture loads, is of version 1.1, holds one view whose frames carry the pose,
// the intrinsics, the mask, the very images written, and directional lights equal to those
// rendered: direction within 1e-9, irradiance the row times the scale.
TEST(ImportPhotometric, LightsImagesAndPose) {
    ImportFixture fx;
    const PhotometricImportResult r = fx.run();
    EXPECT_EQ(r.frames, 8u);
    EXPECT_EQ(r.test_frames, 0u);
    EXPECT_EQ(r.w, 64);
    EXPECT_EQ(r.h, 64);
    EXPECT_EQ(r.triangles, fx.truth.preset.mesh.triangle_count());
    EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();

    const nlohmann::json j = nlohmann::json::parse(read_text_file(fx.out / "capture.json"));
    EXPECT_EQ(j["version"].get<double>(), 1.1);
    EXPECT_EQ(j["color_space"], "linear");
    EXPECT_FALSE(j.contains("saturation"));

    const Capture c = load_capture(fx.out);
    ASSERT_EQ(c.desc.frames.size(), 8u);
    ASSERT_EQ(c.views.size(), 1u);
    EXPECT_EQ(c.desc.mesh_path, "mesh.glb");
    EXPECT_EQ(read_text_file(fx.out / "mesh.glb"), read_text_file(fx.mesh)); // copied byte for byte
    for (std::size_t i = 0; i < c.desc.frames.size(); ++i) {
        const FrameDesc& f = c.desc.frames[i];
        SCOPED_TRACE("frame " + std::to_string(i));
        EXPECT_EQ(f.view_index, 0);
        EXPECT_EQ(f.split, Split::Train);
        EXPECT_EQ(f.file_path, fs::path("images") / fx.truth.images[i].filename());
        EXPECT_EQ(f.mask_path, fs::path("masks/mask.png"));
        EXPECT_EQ(f.intrinsics.w, 64);
        EXPECT_EQ(f.intrinsics.fl_x, fx.truth.intrinsics.fl_x);
        EXPECT_EQ(f.intrinsics.fl_y, fx.truth.intrinsics.fl_x);
        EXPECT_EQ(f.intrinsics.cx, 32.0);
        EXPECT_EQ(f.intrinsics.cy, 32.0);
        for (int col = 0; col < 4; ++col)
            for (int row = 0; row < 4; ++row) EXPECT_NEAR(f.transform[col][row], fx.truth.pose[col][row], 1e-12);
        ASSERT_TRUE(f.light.directional.has_value());
        EXPECT_LE(glm::length(f.light.directional->direction - fx.truth.world_dirs[i]), 1e-9);
        const glm::dvec3 want = fx.truth.intensities[i] * fx.truth.irradiance_scale;
        for (int ch = 0; ch < 3; ++ch) EXPECT_DOUBLE_EQ(f.light.directional->irradiance[ch], want[ch]);
        // The images are the dataset's, decoded as linear.
        const Image source = read_image(fx.truth.images[i], ColorSpace::Linear);
        const Image& got = c.images[i].color;
        ASSERT_EQ(got.pixels.size(), source.pixels.size());
        EXPECT_EQ(got.pixels, source.pixels);
        const std::size_t inside = static_cast<std::size_t>(std::count_if(c.images[i].flags.begin(), c.images[i].flags.end(),
                                                                          [](std::uint8_t fl) { return !(fl & kOutsideMask); }));
        EXPECT_GT(inside, 64u * 64u / 10u); // the object covers a good part of the image
        EXPECT_LT(inside, 64u * 64u);
    }
}

// filenames.txt gives the images in row order, under any names (a subfolder kept); the options
// reach capture.json: sRGB, saturation, principal point, focal lengths, held-out test lights.
TEST(ImportPhotometric, FilenamesAndOptions) {
    ImportFixture fx;
    fs::create_directories(fx.data / "raw");
    std::string names;
    for (std::size_t i = 0; i < fx.truth.images.size(); ++i) {
        const std::string name = i % 2 ? "raw/light_" + std::to_string(i) + ".png" : "img" + std::to_string(i) + ".png";
        fs::rename(fx.truth.images[i], fx.data / name);
        names += "  " + name + " \r\n";
    }
    write_text_file(fx.data / "filenames.txt", names + "\n\n");
    fx.options.color_space = ColorSpace::Srgb;
    fx.options.saturation = 0.95;
    fx.options.cx = 31.0;
    fx.options.cy = 33.5;
    fx.options.fl_y = fx.truth.intrinsics.fl_x * 1.01;
    fx.options.test_every = 3;
    const PhotometricImportResult r = fx.run();
    EXPECT_EQ(r.test_frames, 2u);
    const Capture c = load_capture(fx.out, {.load_images = false});
    EXPECT_EQ(c.desc.color_space, ColorSpace::Srgb);
    EXPECT_EQ(c.desc.saturation, 0.95);
    ASSERT_EQ(c.desc.frames.size(), 8u);
    EXPECT_EQ(c.desc.frames[0].file_path, "images/img0.png");
    EXPECT_EQ(c.desc.frames[1].file_path, "images/raw/light_1.png");
    EXPECT_TRUE(fs::is_regular_file(fx.out / "images/raw/light_1.png"));
    for (std::size_t i = 0; i < 8; ++i) {
        EXPECT_EQ(c.desc.frames[i].split, (i + 1) % 3 == 0 ? Split::Test : Split::Train) << i;
        EXPECT_LE(glm::length(c.desc.frames[i].light.directional->direction - fx.truth.world_dirs[i]), 1e-9);
    }
    EXPECT_EQ(c.desc.frames[0].intrinsics.cx, 31.0);
    EXPECT_EQ(c.desc.frames[0].intrinsics.cy, 33.5);
    EXPECT_EQ(c.desc.frames[0].intrinsics.fl_y, fx.truth.intrinsics.fl_x * 1.01);
}

// A .gltf mesh is converted to mesh.glb; the default identity pose puts the world in the camera
// frame, so the lights' directions are the rows normalized.
TEST(ImportPhotometric, GltfMeshAndIdentityPose) {
    ImportFixture fx;
    // The mesh in the camera's frame: the scan of a dataset whose pose is the identity.
    Mesh camera_mesh = fx.truth.preset.mesh;
    const glm::dmat4 to_camera = glm::inverse(fx.truth.pose);
    for (glm::vec3& p : camera_mesh.positions) p = glm::vec3(to_camera * glm::dvec4(glm::dvec3(p), 1.0));
    for (glm::vec3& n : camera_mesh.normals) n = glm::vec3(glm::dmat3(to_camera) * glm::dvec3(n));
    write_mesh_glb(fx.dir / "glb_inside.glb", camera_mesh);
    // A .gltf with its buffer in a file beside it: the .glb's JSON chunk and its binary chunk.
    const std::string glb = read_text_file(fx.dir / "glb_inside.glb");
    std::uint32_t json_len = 0;
    std::memcpy(&json_len, glb.data() + 12, sizeof json_len);
    nlohmann::json gltf = nlohmann::json::parse(glb.substr(20, json_len));
    write_text_file(fx.dir / "scan.bin", glb.substr(20 + json_len + 8));
    gltf["buffers"][0]["uri"] = "scan.bin";
    write_text_file(fx.dir / "scan.gltf", gltf.dump());
    fx.options.mesh = fx.dir / "scan.gltf";
    fx.options.pose = glm::dmat4(1.0);
    (void)fx.run();
    const Capture c = load_capture(fx.out, {.load_images = false});
    EXPECT_EQ(c.mesh.triangle_count(), camera_mesh.triangle_count());
    EXPECT_EQ(read_text_file(fx.out / "mesh.glb").substr(0, 4), "glTF");
    for (std::size_t i = 0; i < c.desc.frames.size(); ++i)
        EXPECT_LE(glm::length(c.desc.frames[i].light.directional->direction - glm::normalize(fx.truth.camera_dirs[i])), 1e-12);
}

struct Refusal {
    std::string name;
    std::function<void(ImportFixture&)> edit;
    std::string file;    // the file the error names (its last name)
    std::string field;   // the field or line it names
    std::string message; // a part of the message
};

// Each bad input is refused with an InputError naming the file and the line or field, and no
// output folder is left.
TEST(ImportPhotometric, RefusalsNameFileAndLine) {
    const std::vector<Refusal> cases = {
        {"two numbers", [](ImportFixture& fx) { fx.edit_line("light_directions.txt", 7, "0.1 0.2"); }, "light_directions.txt",
         "line 7", "expected 3 numbers, got 2"},
        {"not a number", [](ImportFixture& fx) { fx.edit_line("light_directions.txt", 2, "0.1 abc 0.9"); },
         "light_directions.txt", "line 2", "'abc' is not a number"},
        {"nan", [](ImportFixture& fx) { fx.edit_line("light_intensities.txt", 3, "1 nan 1"); }, "light_intensities.txt", "line 3",
         "not a finite number"},
        {"zero direction", [](ImportFixture& fx) { fx.edit_line("light_directions.txt", 5, "0 0 0"); }, "light_directions.txt",
         "line 5", "the direction is zero"},
        {"negative intensity", [](ImportFixture& fx) { fx.edit_line("light_intensities.txt", 4, "1 -0.5 1"); },
         "light_intensities.txt", "line 4", "-0.5 is negative"},
        {"extra direction row",
         [](ImportFixture& fx) {
             write_text_file(fx.data / "light_directions.txt", read_text_file(fx.data / "light_directions.txt") + "0 0 1\n");
         },
         "light_directions.txt", "rows", "9 rows but 8 images"},
        {"missing intensity row", [](ImportFixture& fx) { fx.edit_line("light_intensities.txt", 8, ""); },
         "light_intensities.txt", "rows", "7 rows but 8 images"},
        {"no directions file", [](ImportFixture& fx) { fs::remove(fx.data / "light_directions.txt"); }, "light_directions.txt",
         "", "file not found"},
        {"no mask", [](ImportFixture& fx) { fs::remove(fx.data / "mask.png"); }, "mask.png", "mask", "file not found"},
        {"mask size", [](ImportFixture& fx) { write_image(fx.data / "mask.png", Image(32, 64, 1, 1.0f), ColorSpace::Linear, 8); },
         "mask.png", "mask", "mask is 32 x 64 but the images are 64 x 64"},
        {"image size",
         [](ImportFixture& fx) { write_image(fx.data / "006.png", Image(64, 63, 3, 0.5f), ColorSpace::Linear, 16); }, "006.png",
         "image 6 of 8", "image is 64 x 63 but the first (001.png) is 64 x 64"},
        {"gap in the numbers", [](ImportFixture& fx) { fs::remove(fx.data / "003.png"); }, "data", "images",
         "image 3 is missing"},
        {"same number twice", [](ImportFixture& fx) { fs::copy_file(fx.data / "002.png", fx.data / "2.png"); }, "", "images",
         "numbers the same image as"},
        {"name leaves the folder",
         [](ImportFixture& fx) { write_text_file(fx.data / "filenames.txt", "001.png\n../scan.glb\n"); }, "filenames.txt",
         "line 2", "is not a file inside the dataset's folder"},
        {"named image missing",
         [](ImportFixture& fx) {
             std::string names;
             for (int i = 1; i <= 8; ++i)
                 names += (i == 4 ? std::string("nothere.png") : fx.truth.images[i - 1].filename().string()) + "\n";
             write_text_file(fx.data / "filenames.txt", names);
         },
         "nothere.png", "filenames.txt line 4", "file not found"},
        {"irradiance out of range", [](ImportFixture& fx) { fx.options.irradiance_scale = 1e16; }, "light_intensities.txt",
         "line 1", "out of range"},
        {"no mesh", [](ImportFixture& fx) { fx.options.mesh = fx.dir / "nothere.glb"; }, "nothere.glb", "--mesh", "not found"},
        {"camera far from the mesh", // caught when the written capture is loaded: names the output's capture.json
         [](ImportFixture& fx) { fx.options.pose[3] = glm::dvec4(0.0, 0.0, 1e9, 1.0); }, "capture.json",
         "frames[0].transform_matrix", "nothing was written"},
    };
    for (const Refusal& c : cases) {
        SCOPED_TRACE(c.name);
        ImportFixture fx({.lights = 8});
        c.edit(fx);
        const InputError e = test::expect_input_error([&] { (void)fx.run(); });
        if (!c.file.empty()) {
            EXPECT_EQ(e.file().filename().string(), c.file) << e.what();
        }
        EXPECT_EQ(e.field(), c.field) << e.what();
        EXPECT_NE(e.message().find(c.message), std::string::npos) << e.what();
        EXPECT_FALSE(fs::exists(fx.out)) << "a refused import left " << fx.out;
        for (const fs::directory_entry& entry : fs::directory_iterator(fx.dir.path()))
            EXPECT_EQ(entry.path().filename().string().find(".capture"), std::string::npos)
                << entry.path(); // no staging, no lock
    }
}

// Options out of range are usage errors naming the option; a refused import into an existing
// capture folder (with --force) leaves it as it was; a non-empty folder needs --force.
TEST(ImportPhotometric, UsageErrorsAndAtomicOutput) {
    ImportFixture fx;
    const auto usage = [&](const std::function<void(PhotometricImportOptions&)>& edit, const std::string& want) {
        PhotometricImportOptions o = fx.options;
        edit(o);
        try {
            (void)import_photometric(fx.data, fx.out, o);
            ADD_FAILURE() << "no UsageError for " << want;
        } catch (const UsageError& e) {
            EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
        }
    };
    usage([](PhotometricImportOptions& o) { o.fl_x = 0.0; }, "--fl: 0 is out of range");
    usage([](PhotometricImportOptions& o) { o.cx = 1e9; }, "--cx");
    usage([](PhotometricImportOptions& o) { o.pose[0][0] = 2.0; }, "--pose: not a rigid transform");
    usage([](PhotometricImportOptions& o) { o.pose = glm::dmat4(-1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1); },
          "--pose: not a valid rotation");
    usage([](PhotometricImportOptions& o) { o.irradiance_scale = -1.0; }, "--irradiance-scale");
    usage([](PhotometricImportOptions& o) { o.test_every = 1; }, "--test-every 1");
    usage([](PhotometricImportOptions& o) { o.saturation = 0.0; }, "--saturation");
    EXPECT_FALSE(fs::exists(fx.out));

    (void)fx.run();
    const std::string before = read_text_file(fx.out / "capture.json");
    EXPECT_THROW((void)fx.run(), UsageError); // not empty, no --force
    fx.options.force = true;
    fx.edit_line("light_directions.txt", 1, "1 2");
    (void)test::expect_input_error([&] { (void)fx.run(); });
    EXPECT_EQ(read_text_file(fx.out / "capture.json"), before);
    fx.edit_line("light_directions.txt", 1, "0 0 1");
    (void)fx.run();
    EXPECT_NE(read_text_file(fx.out / "capture.json"), before);
}

TEST(ImportPhotometric, ParsesRows) {
    std::vector<int> lines;
    const std::vector<glm::dvec3> rows = parse_photometric_rows("\xEF\xBB\xBF 1 2 3\r\n\n+4,5.5e-1\t-6\n  \n7 8 9", "x.txt",
                                                                &lines);
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows[1], glm::dvec3(4.0, 0.55, -6.0));
    EXPECT_EQ(lines, (std::vector<int>{1, 3, 5}));
    const InputError e = test::expect_input_error([] { (void)parse_photometric_rows("1 2 3\n1 2 3 4\n", "x.txt"); });
    EXPECT_EQ(e.field(), "line 2");
    EXPECT_EQ(test::expect_input_error([] { (void)parse_photometric_rows(" \n", "x.txt"); }).message(),
              "no rows (one row of 3 numbers per image)");
}

} // namespace
} // namespace specula
