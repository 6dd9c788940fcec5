// The offscreen raster renderer (engine/render) against the synth ray caster (the
// golden reference of the analytic mode: same radiometry, normal interpolation,
// tangent frame and lobe), plus the pixel convention, the pass bookkeeping, the
// factorized mode's cube-map plumbing, and determinism. Every test runs on lavapipe
// with the validation layer; a validation message fails it (VulkanTest).
//
// Golden tolerance: masked PSNR >= 40 dB, peak = the reference's largest value in the
// compared region. Compared region: pixels both renderers cover, minus a 1-pixel band
// around either mask's edge (rasterization and ray casting resolve a pixel centre that
// sits within float rounding of a silhouette edge differently, and an edge pixel can then
// show a different surface), minus pixels the reference shows black while covered
// (synth's shadowed or light-behind-the-geometric-surface pixels; the renderer's shadow
// map reproduces the cast shadows, tested on their own by the Shadow tests, which keep
// those pixels). Failing comparisons write actual/reference/diff EXRs to
// ${build}/test_out/render/.
#include "capture/camera.h"
#include "core/image.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "gpu/image.h"
#include "gpu/pass_clock.h"
#include "material/core_material.h"
#include "gpu/render_target.h"
#include "gpu/sequence.h"
#include "render/projection.h"
#include "factorization/factorization.h"
#include "render/renderer.h"
#include "synth/presets.h"
#include "synth/rig.h"
#include "synth/shapes.h"
#include "core/timer.h"
#include "synth/render.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

namespace specula::render {
namespace {

using test::VulkanTest;

// ---------------------------------------------------------------------------------------------
// Helpers

Camera make_camera(int w, int h, double fl_x, double fl_y, double cx, double cy, const glm::dvec3& eye,
                   const glm::dvec3& target) {
    return Camera(Intrinsics{w, h, fl_x, fl_y, cx, cy}, look_at_camera_to_world(eye, target, glm::dvec3(0, 1, 0)));
}

/// A smooth albedo texture (periodic in u, like the sphere's longitude). The preset's
/// checker is discontinuous: any resampling into an atlas (which a reconstruction must
/// do) blurs its edges differently from the synth renderer's own bilinear lookup, which
/// would test the resampling, not the renderer. A smooth texture keeps the atlas exact up
/// to bilinear interpolation error while still checking every atlas coordinate.
Image smooth_texture() {
    Image t(512, 256, 3);
    for (int y = 0; y < t.height; ++y)
        for (int x = 0; x < t.width; ++x) {
            const float u = (static_cast<float>(x) + 0.5f) / static_cast<float>(t.width);
            const float v = (static_cast<float>(y) + 0.5f) / static_cast<float>(t.height);
            const float a = 6.2831853f * u, b = 3.1415927f * v;
            t.at(x, y, 0) = 0.45f + 0.30f * std::sin(a) * std::sin(b);
            t.at(x, y, 1) = 0.40f + 0.25f * std::cos(2.0f * a) * std::sin(b);
            t.at(x, y, 2) = 0.35f + 0.25f * std::cos(2.0f * b);
        }
    return t;
}

/// The albedo atlas of a mesh built from the truth: every owned texel gets the
/// synth material's albedo at its particle (eq. 3.2's point, texture coordinates
/// interpolated with the same (s, t)). This is what a perfect diffuse solve yields.
struct TruthAtlas {
    Atlas atlas;
    Image image;
};
TruthAtlas atlas_from_truth(const Mesh& mesh, const synth::Material& material, std::span<const Camera> cameras) {
    TruthAtlas out;
    out.atlas = build_atlas(mesh, cameras, {.max_width = 2048, .max_height = 2048, .texels_per_pixel = 2.0});
    const ParticleSet particles = build_particles(mesh, out.atlas);
    out.image = Image(static_cast<int>(out.atlas.width), static_cast<int>(out.atlas.height), 3, 0.0f);
    for (const Particle& p : particles.particles) {
        glm::vec3 rho = material.albedo_value;
        if (!material.albedo_texture.empty()) {
            const glm::uvec3 t = mesh.triangles[p.triangle];
            const float s = p.bary.x, tt = p.bary.y;
            const glm::vec2 uv = (1.0f - s - tt) * mesh.texcoords[t.x] + s * mesh.texcoords[t.y] + tt * mesh.texcoords[t.z];
            rho = synth::sample_albedo(material.albedo_texture, uv);
        }
        for (int c = 0; c < 3; ++c)
            out.image.at(static_cast<int>(p.texel_x()), static_cast<int>(p.texel_y()), c) = rho[c];
    }
    return out;
}

struct Comparison {
    double psnr = 0.0;
    double max_abs = 0.0;
    double max_rel = 0.0; // |a - r| / r over pixels with r > 10% of the peak
    glm::ivec2 max_rel_at{-1};
    double peak = 0.0;
    std::size_t compared = 0;
    std::size_t excluded_black = 0; // covered by both, black in the reference
    std::size_t coverage_mismatch = 0;
    std::size_t mismatched = 0; // compared pixels with a channel off by more than 3% of the peak
};

bool interior(const std::vector<std::uint8_t>& mask, int w, int h, int x, int y) {
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= w || yy >= h || mask[static_cast<std::size_t>(yy) * w + xx] == 0) return false;
        }
    return true;
}

std::filesystem::path out_dir() {
    const std::filesystem::path dir = std::filesystem::path(SPECULA_TEST_OUT_DIR) / "render";
    std::filesystem::create_directories(dir);
    return dir;
}

/// `keep_black`: compare the pixels the reference shows black too (its shadows).
Comparison compare(const Frame& actual, const synth::RenderedFrame& ref, const std::string& name, double min_psnr,
                   bool keep_black = false) {
    const int w = ref.color.width, h = ref.color.height;
    Comparison c;
    double sse = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            if ((actual.mask[i] != 0) != (ref.mask[i] != 0)) ++c.coverage_mismatch;
            if (!interior(actual.mask, w, h, x, y) || !interior(ref.mask, w, h, x, y)) continue;
            if (!keep_black && ref.color.at(x, y, 0) == 0.0f && ref.color.at(x, y, 1) == 0.0f && ref.color.at(x, y, 2) == 0.0f) {
                ++c.excluded_black;
                continue;
            }
            for (int ch = 0; ch < 3; ++ch) c.peak = std::max(c.peak, static_cast<double>(ref.color.at(x, y, ch)));
        }
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            if (!interior(actual.mask, w, h, x, y) || !interior(ref.mask, w, h, x, y)) continue;
            if (!keep_black && ref.color.at(x, y, 0) == 0.0f && ref.color.at(x, y, 1) == 0.0f && ref.color.at(x, y, 2) == 0.0f) continue;
            ++c.compared;
            bool off = false;
            for (int ch = 0; ch < 3; ++ch) {
                const double r = ref.color.at(x, y, ch), a = actual.color.at(x, y, ch);
                const double e = std::abs(a - r);
                off = off || e > 0.03 * c.peak;
                sse += e * e;
                c.max_abs = std::max(c.max_abs, e);
                if (r > 0.1 * c.peak && e / r > c.max_rel) {
                    c.max_rel = e / r;
                    c.max_rel_at = {x, y};
                }
            }
            if (off) ++c.mismatched;
        }
    const double mse = sse / std::max<double>(1.0, 3.0 * static_cast<double>(c.compared));
    c.psnr = mse > 0.0 ? 10.0 * std::log10(c.peak * c.peak / mse) : 999.0;
    if (c.psnr < min_psnr) {
        const std::filesystem::path dir = out_dir();
        Image diff(w, h, 3);
        for (std::size_t i = 0; i < diff.pixels.size(); ++i) diff.pixels[i] = std::abs(actual.color.pixels[i] - ref.color.pixels[i]);
        write_image(dir / (name + ".actual.exr"), actual.color, ColorSpace::Linear);
        write_image(dir / (name + ".reference.exr"), ref.color, ColorSpace::Linear);
        write_image(dir / (name + ".diff.exr"), diff, ColorSpace::Linear);
    }
    return c;
}

void report(const std::string& name, const Comparison& c) {
    std::printf("%s: PSNR %.2f dB over %zu pixels (peak %.4g, max |err| %.3g, max rel err %.3g at (%d, %d), %zu black reference "
                "pixels excluded, %zu pixels differ in coverage)\n",
                name.c_str(), c.psnr, c.compared, c.peak, c.max_abs, c.max_rel, c.max_rel_at.x, c.max_rel_at.y, c.excluded_black, c.coverage_mismatch);
}

// ---------------------------------------------------------------------------------------------
// Projection (CPU only)

TEST(RenderProjection, MatchesTheCaptureFormula) {
    const Camera cam = make_camera(200, 150, 180.0, 170.0, 91.3, 83.7, {0.4, 0.7, 2.5}, {0.0, 0.1, 0.0});
    const glm::dmat4 m = world_to_clip(cam, 0.5);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < 1000; ++i) {
        const glm::dvec3 p(u(rng), u(rng), u(rng));
        const auto expected = cam.project(p);
        const auto got = project_vulkan(m, cam.intrinsics, p);
        ASSERT_TRUE(expected && got);
        EXPECT_NEAR(got->x, expected->x, 1e-9);
        EXPECT_NEAR(got->y, expected->y, 1e-9);
        // Reversed-Z: near / distance along the view axis, in (0, 1] beyond the near plane.
        EXPECT_NEAR(got->z, 0.5 / -cam.to_camera(p).z, 1e-12);
    }
    EXPECT_FALSE(project_vulkan(m, cam.intrinsics, glm::dvec3(0.8, 1.4, 5.0))); // behind the camera
}

// pixels_of_box: every pixel whose centre a point of the box projects into is inside; the box is
// the corners' extent and a pixel, not more; a box reaching behind the camera gives the whole target.
TEST(RenderProjection, PixelsOfABoxHoldWhatItProjectsTo) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        const glm::dvec3 eye(6.0 * u(rng) - 3.0, 6.0 * u(rng) - 3.0, 3.0 + 4.0 * u(rng));
        const Camera cam = make_camera(160, 120, 150.0, 150.0, 80.0 + 40.0 * (u(rng) - 0.5), 60.0, eye, {0.0, 0.0, 0.0});
        const glm::dmat4 m = world_to_clip(cam, 0.1);
        const glm::dvec3 lo(-u(rng), -u(rng), -u(rng)), hi(u(rng), u(rng), u(rng));
        const PixelBox box = pixels_of_box(m, cam.intrinsics, lo, hi);
        double x_min = 1e9, x_max = -1e9, y_min = 1e9, y_max = -1e9;
        for (int i = 0; i < 2000; ++i) {
            const glm::dvec3 p = lo + (hi - lo) * glm::dvec3(u(rng), u(rng), u(rng));
            const auto f = project_vulkan(m, cam.intrinsics, p);
            ASSERT_TRUE(f);
            x_min = std::min(x_min, f->x);
            x_max = std::max(x_max, f->x);
            y_min = std::min(y_min, f->y);
            y_max = std::max(y_max, f->y);
            // The pixel whose centre is nearest the point, where it is on the target.
            const int px = static_cast<int>(std::floor(f->x)), py = static_cast<int>(std::floor(f->y));
            if (px < 0 || py < 0 || px >= 160 || py >= 120) continue;
            ASSERT_TRUE(px >= box.x0 && px < box.x1 && py >= box.y0 && py < box.y1)
                << "trial " << trial << ": pixel " << px << "," << py << " outside " << box.x0 << ".." << box.x1 << " x "
                << box.y0 << ".." << box.y1;
        }
        // Not the whole target for nothing: within the corners' extent and a pixel.
        for (int corner = 0; corner < 8; ++corner) {
            const auto f = project_vulkan(m, cam.intrinsics,
                                          {(corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y, (corner & 4) ? hi.z : lo.z});
            ASSERT_TRUE(f);
            x_min = std::min(x_min, f->x);
            x_max = std::max(x_max, f->x);
            y_min = std::min(y_min, f->y);
            y_max = std::max(y_max, f->y);
        }
        if (x_max < 0.0 || y_max < 0.0 || x_min > 160.0 || y_min > 120.0) continue;
        EXPECT_GE(box.x0, static_cast<int>(std::floor(x_min)) - 1) << trial;
        EXPECT_LE(box.x1, static_cast<int>(std::ceil(x_max)) + 1) << trial;
        EXPECT_GE(box.y0, static_cast<int>(std::floor(y_min)) - 1) << trial;
        EXPECT_LE(box.y1, static_cast<int>(std::ceil(y_max)) + 1) << trial;
        EXPECT_LT(box.area(), 160 * 120) << trial;
    }
    const Camera cam = make_camera(160, 120, 150.0, 150.0, 80.0, 60.0, {0.0, 0.0, 4.0}, {0.0, 0.0, 0.0});
    const glm::dmat4 m = world_to_clip(cam, 0.1);
    const PixelBox whole{0, 0, 160, 120};
    EXPECT_EQ(pixels_of_box(m, cam.intrinsics, {-1.0, -1.0, -1.0}, {1.0, 1.0, 5.0}), whole); // reaches behind the camera
    const PixelBox small = pixels_of_box(m, cam.intrinsics, {-0.1, -0.1, -0.1}, {0.1, 0.1, 0.1});
    // 150 * 0.1 / 3.9 = 3.85 px each side of the centre (80, 60) at the near face: [76.15, 83.85], and a pixel
    EXPECT_EQ(small, (PixelBox{75, 55, 85, 65}));
    EXPECT_TRUE(pixels_of_box(m, cam.intrinsics, {5.0, 5.0, -1.0}, {6.0, 6.0, 1.0}).empty()); // off the target
    EXPECT_EQ(unite(small, PixelBox{}), small);
    EXPECT_EQ(unite(small, PixelBox{0, 100, 10, 110}), (PixelBox{0, 55, 85, 110}));
    EXPECT_EQ(intersect(small, PixelBox{80, 0, 160, 60}), (PixelBox{80, 55, 85, 60}));
    EXPECT_TRUE(intersect(small, PixelBox{0, 0, 10, 10}).empty());
}

// ---------------------------------------------------------------------------------------------
// GPU images

using RenderGpuImage = VulkanTest;

TEST_F(RenderGpuImage, TextureAndCubeMapRoundTrip) {
    const VkFormat format = gpu::choose_float_texture_format(ctx());
    for (const gpu::ImageKind kind : {gpu::ImageKind::Texture2D, gpu::ImageKind::CubeMap}) {
        const uint32_t w = 7, h = 7, layers = kind == gpu::ImageKind::CubeMap ? 6 : 1;
        std::vector<float> values(std::size_t{w} * h * layers * 3);
        for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.25f * static_cast<float>(i % 37);
        gpu::Image image(ctx(), {.name = "round trip", .kind = kind, .width = w, .height = h, .format = format});
        image.upload(gpu::pack_rgba(values, 3, std::size_t{w} * h * layers, format));
        const std::vector<glm::vec4> back = gpu::unpack_rgba(image.download(), format);
        ASSERT_EQ(back.size(), std::size_t{w} * h * layers);
        for (std::size_t i = 0; i < back.size(); ++i) {
            for (int c = 0; c < 3; ++c) ASSERT_EQ(back[i][c], values[3 * i + static_cast<std::size_t>(c)]) << i;
            ASSERT_EQ(back[i].a, 1.0f);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Renderer

struct SceneData {
    Mesh mesh;
    std::vector<glm::vec2> corner_uv;
    Image albedo;
    [[nodiscard]] Scene scene(const std::optional<SpecularModel>& specular = std::nullopt) const {
        return Scene{.mesh = &mesh, .corner_uv = corner_uv, .albedo = &albedo, .material = {.specular = specular}};
    }
};

/// A cube-map of `res` x `res` faces holding `v` in every texel.
CubeMap constant_cube(uint32_t res, const glm::vec3& v) {
    return CubeMap{res, std::vector<glm::vec3>(std::size_t{6} * res * res, v)};
}

/// A mesh with a constant 1x1 "atlas" (every corner samples the one texel).
SceneData constant_albedo(Mesh mesh, const glm::vec3& rho) {
    SceneData s;
    s.corner_uv.assign(3 * mesh.triangles.size(), glm::vec2(0.5f));
    s.mesh = std::move(mesh);
    s.albedo = Image(1, 1, 3);
    for (int c = 0; c < 3; ++c) s.albedo.at(0, 0, c) = rho[c];
    return s;
}

using RenderTest = VulkanTest;

TEST_F(RenderTest, PixelConventionMatchesTheCaptureFormula) {
    // A rectangle facing the camera whose corners project to known sub-pixel positions,
    // with an off-centre principal point and non-square pixels: the covered pixels must
    // be exactly those whose centres (i + 0.5, j + 0.5) lie inside.
    const Camera cam = make_camera(64, 48, 70.0, 55.0, 29.3, 21.6, {0.0, 0.0, 3.0}, {0.0, 0.0, 0.0});
    const double depth = 2.0; // plane Z_cam = -2
    const glm::dvec2 lo(10.25, 7.7), hi(40.6, 33.2);
    const auto unproject = [&](double x, double y) {
        const glm::dvec3 c((x - cam.intrinsics.cx) / cam.intrinsics.fl_x * depth,
                           -(y - cam.intrinsics.cy) / cam.intrinsics.fl_y * depth, -depth);
        return glm::vec3(glm::dvec3(cam.camera_to_world * glm::dvec4(c, 1.0)));
    };
    Mesh quad;
    quad.positions = {unproject(lo.x, lo.y), unproject(hi.x, lo.y), unproject(hi.x, hi.y), unproject(lo.x, hi.y)};
    quad.normals.assign(4, glm::vec3(0, 0, 1));
    quad.triangles = {{0, 1, 2}, {0, 2, 3}};
    const glm::dvec2 corners[4] = {lo, {hi.x, lo.y}, hi, {lo.x, hi.y}};
    for (int k = 0; k < 4; ++k) {
        const auto px = cam.project(glm::dvec3(quad.positions[static_cast<std::size_t>(k)]));
        ASSERT_TRUE(px);
        EXPECT_NEAR(glm::distance(*px, corners[k]), 0.0, 1e-4);
    }
    EXPECT_FALSE(is_closed_outward(quad)); // open: Culling::Auto draws both sides
    const SceneData data = constant_albedo(quad, glm::vec3(0.5f));
    Renderer r(ctx(), data.scene());
    EXPECT_FALSE(r.culls_back_faces());
    const Frame f = r.render(cam, PointLight{{0.0, 0.0, 3.0}, {1.0, 1.0, 1.0}}, {.mode = Mode::Diffuse});
    std::size_t wrong = 0, covered = 0;
    for (int j = 0; j < 48; ++j)
        for (int i = 0; i < 64; ++i) {
            const bool inside = i + 0.5 > lo.x && i + 0.5 < hi.x && j + 0.5 > lo.y && j + 0.5 < hi.y;
            const bool got = f.mask[static_cast<std::size_t>(j) * 64 + i] != 0;
            wrong += inside != got;
            covered += got;
        }
    EXPECT_EQ(wrong, 0u);
    EXPECT_EQ(covered, 31u * 25u); // columns 10..40, rows 8..32
    EXPECT_EQ(f.info.covered_pixels, covered);

    // Tiny triangles (0.3 pixel) around points p near pixel centres, p projected with the
    // capture formula: each covers exactly the pixel floor(p), the one whose centre it holds.
    // Half a pixel off (centres at integers) or a flipped row order would miss or move them.
    Mesh tris;
    std::vector<glm::ivec2> expected;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> jitter(-0.1, 0.1);
    for (int k = 0; k < 24; ++k) {
        const glm::ivec2 pixel(3 + (k * 7) % 58, 2 + (k * 5) % 44);
        const glm::dvec2 p(pixel.x + 0.5 + jitter(rng), pixel.y + 0.5 + jitter(rng));
        const auto base = static_cast<uint32_t>(tris.positions.size());
        tris.positions.push_back(unproject(p.x - 0.3, p.y - 0.3));
        tris.positions.push_back(unproject(p.x + 0.3, p.y - 0.3));
        tris.positions.push_back(unproject(p.x, p.y + 0.3));
        tris.triangles.push_back({base, base + 1, base + 2});
        const auto back = cam.project(glm::dvec3(cam.camera_to_world * glm::dvec4(
            (p.x - cam.intrinsics.cx) / cam.intrinsics.fl_x * depth, -(p.y - cam.intrinsics.cy) / cam.intrinsics.fl_y * depth,
            -depth, 1.0)));
        ASSERT_TRUE(back);
        EXPECT_EQ(glm::ivec2(glm::floor(*back)), pixel);
        expected.push_back(pixel);
    }
    tris.normals.assign(tris.positions.size(), glm::vec3(0, 0, 1));
    const SceneData tdata = constant_albedo(tris, glm::vec3(0.5f));
    Renderer rt(ctx(), tdata.scene());
    const Frame ft = rt.render(cam, PointLight{{0.0, 0.0, 3.0}, {1.0, 1.0, 1.0}}, {.mode = Mode::Diffuse});
    EXPECT_EQ(ft.info.covered_pixels, expected.size());
    for (const glm::ivec2& px : expected) EXPECT_NE(ft.mask[static_cast<std::size_t>(px.y) * 64 + px.x], 0) << px.x << "," << px.y;
}

TEST_F(RenderTest, BackFaceCullingKeepsAConvexObject) {
    // Front faces (counter-clockwise seen from outside) survive culling, so the projection's
    // y flip kept the orientation Vulkan's front-face rule expects.
    synth::Preset sphere = synth::make_preset("sphere");
    const SceneData data = constant_albedo(sphere.mesh, glm::vec3(0.6f));
    const Camera cam = make_camera(64, 64, 80.0, 80.0, 32.0, 32.0, {0.3, 0.4, 2.0}, {0, 0, 0});
    const PointLight light{{1.0, 1.5, 2.0}, {4.0, 4.0, 4.0}};
    EXPECT_TRUE(is_closed_outward(sphere.mesh)); // welded across the texture seam and the poles
    Renderer all(ctx(), data.scene(sphere.material.lobe), {.culling = Culling::Never});
    Renderer culled(ctx(), data.scene(sphere.material.lobe), {.culling = Culling::Always});
    Renderer automatic(ctx(), data.scene(sphere.material.lobe));
    EXPECT_FALSE(all.culls_back_faces());
    EXPECT_TRUE(culled.culls_back_faces());
    EXPECT_TRUE(automatic.culls_back_faces());
    const Frame a = all.render(cam, light), b = culled.render(cam, light);
    EXPECT_GT(a.info.covered_pixels, 1000u);
    EXPECT_EQ(a.mask, b.mask);
    EXPECT_EQ(a.color.pixels, b.color.pixels);
}

TEST_F(RenderTest, SphereAnalyticMatchesSynthWithAtlasFromTruth) {
    // The sphere preset (pepsi lobe; smooth albedo, see smooth_texture) is convex: nothing is shadowed.
    synth::Preset preset = synth::make_preset("sphere");
    preset.material.albedo_texture = smooth_texture();
    const Camera cam = make_camera(128, 128, 150.0, 150.0, 61.3, 66.8, {0.3, 0.4, 2.0}, {0, 0, 0});
    const PointLight light{{1.0, 1.5, 2.2}, {5.0, 4.5, 4.0}};
    const TruthAtlas atlas = atlas_from_truth(preset.mesh, preset.material, std::span<const Camera>(&cam, 1));
    Renderer r(ctx(), {.mesh = &preset.mesh, .corner_uv = atlas.atlas.corner_uv, .albedo = &atlas.image,
                       .material = {.specular = preset.material.lobe}});
    const Frame f = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic});
    EXPECT_TRUE(f.info.diffuse_pass);
    EXPECT_TRUE(f.info.specular_pass);
    const synth::RenderedFrame ref = synth::Renderer(preset.mesh, preset.material).render(cam, light);
    const Comparison c = compare(f, ref, "sphere_analytic", 40.0);
    report("sphere analytic vs synth", c);
    EXPECT_GE(c.psnr, 40.0);
    EXPECT_GT(c.compared, 4000u);
}

TEST_F(RenderTest, CanAnalyticMatchesSynthWithConstantAlbedo) {
    synth::Preset preset = synth::make_preset("can");
    preset.material.albedo_texture = Image(); // constant albedo: the atlas is one texel
    preset.material.albedo_value = glm::vec3(0.62f, 0.05f, 0.06f);
    const SceneData data = constant_albedo(preset.mesh, preset.material.albedo_value);
    const Camera cam = make_camera(128, 128, 150.0, 150.0, 64.0, 64.0, {0.9, 0.9, 2.3}, {0.0, 0.55, 0.0});
    const PointLight light{{1.6, 1.4, 1.8}, {6.0, 6.0, 6.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const Frame f = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic});
    const synth::RenderedFrame ref = synth::Renderer(preset.mesh, preset.material).render(cam, light);
    const Comparison c = compare(f, ref, "can_analytic", 40.0);
    report("can analytic vs synth", c);
    EXPECT_GE(c.psnr, 40.0);
    EXPECT_GT(c.compared, 2000u);
}

// Cast shadows: the knot preset shadows itself wherever the light sits. Against synth's
// ray-traced image with its shadows kept (keep_black), the shadow-mapped render must be far
// closer than the thesis's unshadowed one: at least 30 dB more masked PSNR, and at most 0.03%
// of the compared pixels (2 of 8,500) off by more than 3% of the peak (what is left: the shadow
// map's edge aliasing, a texel of 1/1000 of the bounding sphere against synth's exact edge, and
// the normal offset's shift of the edge; measured with lavapipe's D16 map, which is not filtered:
// +31.9 dB and 1 pixel, 7.6% unshadowed; with the offset of a texel and more used until
// 2026-12, +24.6 dB and 4 pixels). Every pass shader applies the same light_visibility: fused
// and separate passes must agree.
// A directional light (capture format 1.1) draws through its stand-in point light 5e5 D
// away (capture.h), whose shadow map is a parallel projection (renderer.cpp light_frustum):
// against synth's exact directional light, the same bounds as the point light's.
void expect_knot_self_shadowing(gpu::Context& context, const PointLight& light, const char* name) {
    synth::Preset preset = synth::make_preset("knot");
    preset.material.albedo_texture = Image();
    preset.material.albedo_value = glm::vec3(0.55f, 0.45f, 0.35f);
    const SceneData data = constant_albedo(preset.mesh, preset.material.albedo_value);
    const Camera cam = make_camera(160, 160, 170.0, 170.0, 80.0, 80.0, {0.4, 1.2, 4.2}, {0.0, 0.0, 0.0});
    std::printf("%s light:\n", name);
    Renderer r(context, data.scene(preset.material.lobe));
    const synth::RenderedFrame ref = synth::Renderer(preset.mesh, preset.material).render(cam, light);
    ASSERT_GT(ref.shadowed_pixels, 500u) << "the scene must show a cast shadow";

    const Frame on = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic});
    const Frame off = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic, .shadows = false});
    EXPECT_TRUE(on.info.shadow_pass);
    EXPECT_TRUE(on.info.shadow_note.empty()) << on.info.shadow_note;
    EXPECT_FALSE(off.info.shadow_pass);
    EXPECT_EQ(off.info.shadow_note, "shadows off");
    const Comparison c_on = compare(on, ref, "knot_shadows", 99.0, /*keep_black=*/true);
    const Comparison c_off = compare(off, ref, "knot_no_shadows", 0.0, /*keep_black=*/true);
    report("knot with shadows vs synth (shadowed pixels kept)", c_on);
    report("knot without shadows vs synth (shadowed pixels kept)", c_off);
    std::printf("knot: %zu shadowed reference pixels; PSNR gain %.2f dB; mismatched pixels %.2f%% with shadows, %.2f%% without\n",
                ref.shadowed_pixels, c_on.psnr - c_off.psnr, 100.0 * c_on.mismatched / std::max<std::size_t>(1, c_on.compared),
                100.0 * c_off.mismatched / std::max<std::size_t>(1, c_off.compared));
    EXPECT_GT(c_on.compared, 5000u);
    EXPECT_GE(c_on.psnr - c_off.psnr, 30.0);
    EXPECT_LE(static_cast<double>(c_on.mismatched), 3e-4 * static_cast<double>(c_on.compared));

    // The fused pass applies the same visibility as the two separate passes.
    const Frame fused =
        r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic, .passes = Passes::Fused});
    double max_diff = 0.0;
    for (std::size_t i = 0; i < fused.color.pixels.size(); ++i)
        max_diff = std::max(max_diff, static_cast<double>(std::abs(fused.color.pixels[i] - on.color.pixels[i])));
    EXPECT_LE(max_diff, 1e-4 * c_on.peak);
}

TEST_F(RenderTest, ShadowMapReproducesTheKnotsSelfShadowing) {
    expect_knot_self_shadowing(ctx(), PointLight{{2.2, 3.0, 2.0}, {30.0, 30.0, 30.0}, std::nullopt}, "point");
    const glm::dvec3 p(2.2, 3.0, 2.0);
    const Bounds b = mesh_bounds(synth::make_preset("knot").mesh);
    expect_knot_self_shadowing(ctx(), directional_stand_in(DirectionalLight{glm::normalize(p), glm::dvec3(30.0 / glm::dot(p, p))}, b),
                               "directional");
}

// The shadow map's frustum is the cone from the light that holds the mesh's vertices, not its
// bounding sphere's (renderer.cpp light_frustum): the woodenpot, a squat bowl whose box's sphere is
// half as wide again as the bowl seen from the side, gets texels two thirds as large, and the rim's
// shadow inside the bowl an edge nearer synth's ray-traced one. Measured against it (shadowed
// pixels kept): 44.4 dB masked PSNR with the mesh's cone, 40.8 dB with the sphere's.
TEST_F(RenderTest, ShadowMapFrustumHoldsTheMeshNotItsBoundingSphere) {
    synth::Preset preset = synth::make_preset("woodenpot");
    preset.material.albedo_texture = Image();
    preset.material.albedo_value = glm::vec3(0.55f, 0.45f, 0.35f);
    const SceneData data = constant_albedo(preset.mesh, preset.material.albedo_value);
    const Camera cam = make_camera(200, 160, 190.0, 190.0, 100.0, 80.0, {0.3, 1.9, 1.5}, {0.0, 0.25, 0.0});
    const PointLight light{{-2.2, 2.4, 0.6}, {30.0, 30.0, 30.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const synth::RenderedFrame ref = synth::Renderer(preset.mesh, preset.material).render(cam, light);
    ASSERT_GT(ref.shadowed_pixels, 500u) << "the rim must shadow the inside";
    const Frame on = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic});
    EXPECT_TRUE(on.info.shadow_pass);
    const Comparison c = compare(on, ref, "woodenpot_shadows", 99.0, /*keep_black=*/true);
    report("woodenpot with shadows vs synth (shadowed pixels kept)", c);
    std::printf("woodenpot: %zu shadowed reference pixels; PSNR %.2f dB; mismatched pixels %zu of %zu\n", ref.shadowed_pixels, c.psnr,
                c.mismatched, c.compared);
    EXPECT_GT(c.compared, 5000u);
    EXPECT_GE(c.psnr, 43.0);
}

// No self-shadowing where nothing casts a shadow ("shadow acne"): a convex sphere, lit from in
// front, from the side and from behind its limb as seen by the camera (so that the terminator,
// where the normal offset's grazing term and the depth bias matter most, is in view), renders the
// same with its shadow map as without. A pixel is acne where the unshadowed render is brighter
// than 2% of the frame's peak (away from the terminator, whose n.u the rasterized facets and
// the interpolated normal disagree on) and the shadowed one is more than 1% darker. With no normal
// offset and no depth bias the renderer showed acne on hundreds of these pixels; with the offset
// the renderer uses (a quarter texel, renderer.cpp kNormalOffsetConstant) none, nor down to 0.1
// texel (two pixels at 0.05) with the shadow map's frustum fitted to the vertices.
TEST_F(RenderTest, ShadowMapPutsNoAcneOnAConvexSphere) {
    synth::Preset preset = synth::make_preset("sphere");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.6f));
    const Camera cam = make_camera(128, 128, 150.0, 150.0, 64.0, 64.0, {0.0, 0.0, 3.0}, {0, 0, 0});
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const std::array<glm::dvec3, 5> lights = {glm::dvec3{0.3, 0.4, 3.0}, glm::dvec3{3.0, 0.5, 0.5}, glm::dvec3{-2.5, 2.0, -0.3},
                                              glm::dvec3{0.2, -3.0, -1.5}, glm::dvec3{2.0, 2.0, -2.0}};
    for (const glm::dvec3& p : lights) {
        const PointLight light{p, {8.0, 8.0, 8.0}};
        const Frame on = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic});
        const Frame off = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic, .shadows = false});
        ASSERT_TRUE(on.info.shadow_pass) << on.info.shadow_note;
        float peak = 0.0f;
        for (float v : off.color.pixels) peak = std::max(peak, v);
        std::size_t lit = 0, acne = 0;
        for (std::size_t i = 0; i < off.color.pixels.size(); ++i) {
            const float want = off.color.pixels[i];
            if (!(want > 0.02f * peak)) continue;
            ++lit;
            if (on.color.pixels[i] < 0.99f * want) ++acne;
        }
        std::printf("light (%.1f, %.1f, %.1f): %zu lit pixel channels, %zu darker with the shadow map\n", p.x, p.y, p.z, lit, acne);
        EXPECT_GT(lit, 300u);
        EXPECT_EQ(acne, 0u) << "light at (" << p.x << ", " << p.y << ", " << p.z << ")";
    }
}

// A light inside (or too close to) the bounding sphere gets no shadow map, and says so.
TEST_F(RenderTest, ShadowsNeedTheLightOutsideTheBoundingSphere) {
    const synth::Preset preset = synth::make_preset("sphere");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    Renderer r(ctx(), data.scene());
    const Camera cam = make_camera(32, 32, 40.0, 40.0, 16.0, 16.0, {0.0, 0.0, 2.0}, {0, 0, 0});
    const Frame inside = r.render(cam, PointLight{{0.0, 0.0, 0.52}, {1.0, 1.0, 1.0}}, {.mode = Mode::Diffuse});
    EXPECT_FALSE(inside.info.shadow_pass);
    EXPECT_NE(inside.info.shadow_note.find("bounding sphere"), std::string::npos) << inside.info.shadow_note;
    EXPECT_GT(inside.info.covered_pixels, 0u);
    const Frame outside = r.render(cam, PointLight{{0.0, 0.0, 3.0}, {1.0, 1.0, 1.0}}, {.mode = Mode::Diffuse});
    EXPECT_TRUE(outside.info.shadow_pass);
    EXPECT_TRUE(outside.info.shadow_note.empty());
}

TEST_F(RenderTest, DiffuseOnlyOfALambertianSphereMatchesSynth) {
    const Camera cam = make_camera(128, 128, 150.0, 150.0, 64.0, 64.0, {-0.5, 0.3, 1.9}, {0, 0, 0});
    const PointLight light{{-1.5, 1.0, 1.0}, {3.0, 3.0, 3.0}};
    synth::Preset preset = synth::make_preset("sphere", /*lambertian=*/true);

    // 1. Constant albedo: the renderer alone. Both sides evaluate the same float formula at
    //    the same surface point, so the tolerance is float rounding: relative error <= 1e-4
    //    on pixels brighter than 10% of the peak, PSNR >= 80 dB.
    preset.material.albedo_texture = Image();
    preset.material.albedo_value = glm::vec3(0.7f, 0.5f, 0.3f);
    const SceneData data = constant_albedo(preset.mesh, preset.material.albedo_value);
    Renderer rc(ctx(), data.scene());
    const Frame fc = rc.render(cam, light, {.mode = Mode::Diffuse});
    EXPECT_FALSE(fc.info.specular_pass);
    EXPECT_EQ(fc.info.specular_note, "mode diffuse");
    const synth::RenderedFrame refc = synth::Renderer(preset.mesh, preset.material).render(cam, light);
    const Comparison cc = compare(fc, refc, "sphere_diffuse_constant", 80.0);
    report("lambertian sphere (constant albedo) diffuse vs synth", cc);
    EXPECT_GE(cc.psnr, 80.0);
    EXPECT_LE(cc.max_rel, 1e-4);

    // 2. Smooth albedo through an atlas built from the truth: adds the atlas resampling.
    //    Tolerance: PSNR >= 50 dB and relative error <= 2%; the error sits on patch edges,
    //    where gutter texels hold the value at the edge rather than its linear
    //    continuation, so bilinear filtering there is not exact (measured: 63 dB, 1.4%).
    preset.material.albedo_texture = smooth_texture();
    const TruthAtlas atlas = atlas_from_truth(preset.mesh, preset.material, std::span<const Camera>(&cam, 1));
    Renderer r(ctx(), {.mesh = &preset.mesh, .corner_uv = atlas.atlas.corner_uv, .albedo = &atlas.image});
    const Frame f = r.render(cam, light, {.mode = Mode::Diffuse});
    const synth::RenderedFrame ref = synth::Renderer(preset.mesh, preset.material).render(cam, light);
    const Comparison c = compare(f, ref, "sphere_diffuse_atlas", 50.0);
    report("lambertian sphere (atlas from truth) diffuse vs synth", c);
    EXPECT_GE(c.psnr, 50.0);
    EXPECT_LE(c.max_rel, 0.02);
}

TEST_F(RenderTest, PassesAddUpAndAZeroLobeLeavesTheSpecularPassOut) {
    const synth::Preset preset = synth::make_preset("sphere");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.4f, 0.5f, 0.6f));
    const Camera cam = make_camera(64, 64, 80.0, 80.0, 32.0, 32.0, {0.3, 0.4, 2.0}, {0, 0, 0});
    const PointLight light{{1.0, 1.5, 2.0}, {4.0, 4.0, 4.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const Frame both = r.render(cam, light, {.mode = Mode::Both});
    const Frame diffuse = r.render(cam, light, {.mode = Mode::Diffuse});
    const Frame specular = r.render(cam, light, {.mode = Mode::Specular});
    EXPECT_TRUE(specular.info.specular_pass);
    EXPECT_FALSE(specular.info.diffuse_pass);
    EXPECT_EQ(both.mask, diffuse.mask);
    EXPECT_EQ(both.mask, specular.mask);
    double spec_energy = 0.0;
    for (std::size_t i = 0; i < both.color.pixels.size(); ++i) {
        const float sum = diffuse.color.pixels[i] + specular.color.pixels[i];
        EXPECT_NEAR(both.color.pixels[i], sum, 1e-6f * std::max(1.0f, std::abs(sum)));
        spec_energy += specular.color.pixels[i];
    }
    EXPECT_GT(spec_energy, 0.0);
    ASSERT_TRUE(both.info.diffuse_gpu_ms.has_value());
    ASSERT_TRUE(both.info.specular_gpu_ms.has_value());
    EXPECT_GT(both.info.wall_ms, 0.0);

    r.set_specular(LafortuneRgb{});
    const Frame zero = r.render(cam, light, {.mode = Mode::Both});
    EXPECT_FALSE(zero.info.specular_pass);
    EXPECT_NE(zero.info.specular_note.find("no lobe"), std::string::npos);
    EXPECT_FALSE(zero.info.specular_gpu_ms.has_value());
    EXPECT_EQ(zero.color.pixels, diffuse.color.pixels);
}

TEST_F(RenderTest, FactorizedModeLooksUpBothCubeMaps) {
    // With constant cube-maps G = a and H = b, the factorized specular term is a b I cos / d^2:
    // the diffuse term of an albedo rho = pi a b. Tolerance 1e-5 relative (float rounding).
    const synth::Preset preset = synth::make_preset("sphere");
    const glm::vec3 a(0.3f, 0.5f, 0.7f), b(0.9f, 0.4f, 0.2f);
    const SceneData spec_data = constant_albedo(preset.mesh, glm::vec3(0.0f));
    const SceneData diff_data = constant_albedo(preset.mesh, glm::pi<float>() * a * b);
    const Camera cam = make_camera(64, 64, 80.0, 80.0, 30.0, 33.0, {0.3, 0.4, 2.0}, {0, 0, 0});
    const PointLight light{{1.0, 1.5, 2.0}, {4.0, 4.0, 4.0}};
    Renderer spec(ctx(), spec_data.scene(preset.material.lobe));
    EXPECT_FALSE(spec.has_factorization());
    EXPECT_THROW((void)spec.render(cam, light, {.mode = Mode::Specular, .specular = SpecularPath::Factorized}), Error);
    spec.set_factorization(FactorizedSpecular{.terms = {{constant_cube(8, a), constant_cube(16, b)}}});
    EXPECT_TRUE(spec.has_factorization());
    const Frame fs = spec.render(cam, light, {.mode = Mode::Specular, .specular = SpecularPath::Factorized});
    Renderer diff(ctx(), diff_data.scene());
    const Frame fd = diff.render(cam, light, {.mode = Mode::Diffuse});
    EXPECT_EQ(fs.mask, fd.mask);
    double energy = 0.0;
    for (std::size_t i = 0; i < fs.color.pixels.size(); ++i) {
        EXPECT_NEAR(fs.color.pixels[i], fd.color.pixels[i], 1e-5f * std::max(1e-3f, fd.color.pixels[i]));
        energy += fs.color.pixels[i];
    }
    EXPECT_GT(energy, 0.0);
}

TEST_F(RenderTest, FactorizedModeSumsTheTermsAndClampsAtZero) {
    // Constant cube-maps: the specular term is max(0, sum_k a_k b_k) I cos / d^2, the diffuse
    // term of rho = pi max(0, sum_k a_k b_k). Term 3 makes the blue channel's sum negative
    // (0 after the clamp). Tolerance 1e-5 relative (float rounding).
    const synth::Preset preset = synth::make_preset("sphere");
    const std::vector<FactorTerm> terms = {
        {constant_cube(8, {0.3f, 0.5f, 0.7f}), constant_cube(16, {0.9f, 0.4f, 0.2f})},
        {constant_cube(8, {0.2f, -0.1f, 0.1f}), constant_cube(8, {0.5f, 0.5f, 0.5f})},
        {constant_cube(4, {0.1f, 0.1f, -1.0f}), constant_cube(16, {0.3f, 0.2f, 0.5f})},
        {constant_cube(8, {0.05f, 0.0f, 0.0f}), constant_cube(8, {1.0f, 1.0f, 1.0f})},
    };
    const Camera cam = make_camera(64, 64, 80.0, 80.0, 30.0, 33.0, {0.3, 0.4, 2.0}, {0, 0, 0});
    const PointLight light{{1.0, 1.5, 2.0}, {4.0, 4.0, 4.0}};
    const SceneData spec_data = constant_albedo(preset.mesh, glm::vec3(0.0f));
    Renderer spec(ctx(), spec_data.scene(preset.material.lobe));
    for (std::size_t k = 1; k <= terms.size(); ++k) {
        spec.set_factorization(FactorizedSpecular{.terms = {terms.begin(), terms.begin() + static_cast<std::ptrdiff_t>(k)}});
        EXPECT_EQ(spec.factorization_terms(), k);
        glm::vec3 sum(0.0f);
        for (std::size_t j = 0; j < k; ++j)
            for (int c = 0; c < 3; ++c) sum[c] += terms[j].g.texels[0][c] * terms[j].h.texels[0][c];
        const SceneData diff_data = constant_albedo(preset.mesh, glm::pi<float>() * glm::max(sum, glm::vec3(0.0f)));
        Renderer diff(ctx(), diff_data.scene());
        const Frame fd = diff.render(cam, light, {.mode = Mode::Diffuse});
        for (const Passes passes : {Passes::Separate, Passes::Fused}) {
            // Fused: diffuse (0 albedo) + specular in one pass.
            const Frame fs = spec.render(cam, light, {.mode = passes == Passes::Fused ? Mode::Both : Mode::Specular,
                                                      .specular = SpecularPath::Factorized, .passes = passes});
            EXPECT_EQ(fs.mask, fd.mask);
            for (std::size_t i = 0; i < fs.color.pixels.size(); ++i)
                ASSERT_NEAR(fs.color.pixels[i], fd.color.pixels[i], 1e-5f * std::max(1e-3f, fd.color.pixels[i]))
                    << "K = " << k << " pixel value " << i;
        }
    }
    EXPECT_THROW(spec.set_factorization(FactorizedSpecular{.terms = std::vector<FactorTerm>(5, terms[0])}), Error);
    EXPECT_THROW(spec.set_factorization(FactorizedSpecular{}), Error);
    EXPECT_EQ(spec.factorization_terms(), 4u); // a refused call changes nothing
}

/// The first k terms of f's cube-maps, looked up in `param` with `warp` (not necessarily f's own).
FactorizedSpecular first_terms(const factorization::Factorization& f, uint32_t k, FactorParam param,
                               glm::vec4 warp = glm::vec4(1.0f)) {
    return {.param = param, .warp = warp, .terms = {f.cubes.terms.begin(), f.cubes.terms.begin() + k}};
}

/// Masked PSNR of `a` against `ref` over pixels both cover, peak = ref's largest value there.
double masked_psnr(const Frame& a, const Frame& ref) {
    double peak = 0.0, se = 0.0;
    std::size_t n = 0;
    for (std::size_t p = 0; p < ref.mask.size(); ++p) {
        if (!ref.mask[p] || !a.mask[p]) continue;
        for (int c = 0; c < 3; ++c) {
            const double r = ref.color.pixels[3 * p + static_cast<std::size_t>(c)];
            const double d = a.color.pixels[3 * p + static_cast<std::size_t>(c)] - r;
            peak = std::max(peak, r);
            se += d * d;
            ++n;
        }
    }
    return n == 0 || se == 0.0 ? 999.0 : 10.0 * std::log10(peak * peak / (se / static_cast<double>(n)));
}

/// View `view` (0..4) of the factorized-against-analytic tests on the can: the camera turning
/// around it at 128 px, the light beside the camera.
std::pair<Camera, PointLight> can_view(int view) {
    const double a = 0.4 + 1.2 * view;
    const glm::dvec3 eye(2.4 * std::cos(a), 0.9 + 0.2 * view, 2.4 * std::sin(a));
    const glm::dvec3 light_pos(2.0 * std::cos(a + 0.5 + 0.3 * view), 1.6, 2.0 * std::sin(a + 0.5 + 0.3 * view));
    return {make_camera(128, 128, 150.0, 150.0, 64.0, 64.0, eye, {0.0, 0.55, 0.0}), PointLight{light_pos, {6.0, 6.0, 6.0}}};
}

// Issue 5's criterion, "factorized within 1 dB of analytic" (masked PSNR against a captured
// image), checked here directly on the factorized-vs-analytic PSNR of the same Renderer on
// the can (its lobe, albedo and mesh), five views and lights. If the analytic render's error
// against a capture has MSE e_a and the factorized render differs from the analytic one by
// MSE e_f, uncorrelated, the factorized render's PSNR is 10 log10(1 + e_f / e_a) below the
// analytic one: within 1 dB needs e_f <= 0.26 e_a, i.e. PSNR(factorized vs analytic) >=
// PSNR(analytic vs capture) + 5.9 dB. Measured on the can at 256 px (specula evaluate):
// analytic 41.7 dB (train) / 33.5 dB (test) against the capture, so the criterion asks for
// >= 39.4 dB (test) and >= 47.6 dB (train) here.
// In the thesis's GSHD (lavapipe, the five views): K = 1 31.6 to 33.3 dB, automatic K (= 4)
// 38.8 to 46.0 dB: the can's lobe, |Cx| > Cz, keeps 15% matrix RMS at K = 4. In the mirrored
// GSHD (shared/gshd.h part 4), which the automatic choice keeps for this lobe: K = 3 on its
// default grids (h 16 x d 51) 57.1 to 63.3 dB (on 16 x 16 grids 47.4 to 48.1 dB: the rest was
// interpolation between cells); the same cube-maps looked up as plain GSHD 29 to 32 dB. In the
// warped GSHD (part 5), which the automatic choice keeps: K = 1 (exactly rank 1 per channel) on
// its default grids (h 16 x d 93), times the lobe's radial factor: 76.1 to 76.3 dB. Asserted
// (worst view): plain automatic K at least 5 dB better than K = 1 and >= 38 dB; mirrored at least
// 15 dB better than plain and >= 55 dB; warped at least 10 dB better than mirrored and >= 70 dB; mirrored cube-maps looked up as plain
// worse than plain K = 1, and warped ones looked up without the radial factor (as mirrored) worse
// than plain K = 1.
TEST_F(RenderTest, FactorizedTracksAnalyticOnTheCanWithSeveralTerms) {
    const synth::Preset preset = synth::make_preset("can");
    const LafortuneRgb lobe{preset.material.lobe.cx, preset.material.lobe.cz, preset.material.lobe.n};
    const factorization::Factorization f = factorization::factorize_cpu(lobe, {.param = FactorParam::Gshd});
    const factorization::Factorization fm = factorization::factorize_cpu(lobe, {.param = FactorParam::Mirrored});
    const factorization::Factorization fw = factorization::factorize_cpu(lobe, {});
    ASSERT_EQ(fw.cubes.param, FactorParam::Warped) << fw.param_choice.reason;
    const SceneData data = constant_albedo(preset.mesh, preset.material.albedo_value);
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const FactorizedSpecular all = first_terms(f, f.term_count(), FactorParam::Gshd);
    const FactorizedSpecular one = first_terms(f, 1, FactorParam::Gshd);
    const FactorizedSpecular mirrored = first_terms(fm, fm.term_count(), fm.cubes.param);
    const FactorizedSpecular mirrored_as_plain = first_terms(fm, fm.term_count(), FactorParam::Gshd);
    const FactorizedSpecular warped = first_terms(fw, fw.term_count(), fw.cubes.param, fw.cubes.warp);
    const FactorizedSpecular warped_as_mirrored = first_terms(fw, fw.term_count(), FactorParam::Mirrored);
    double worst_one = 999.0, worst_all = 999.0, worst_mirrored = 999.0, worst_wrong = 999.0;
    double worst_warped = 999.0, worst_warped_wrong = 999.0;
    for (int view = 0; view < 5; ++view) {
        const auto [cam, light] = can_view(view);
        const Settings factorized{.mode = Mode::Both, .specular = SpecularPath::Factorized};
        const Frame analytic = r.render(cam, light, {.mode = Mode::Both, .specular = SpecularPath::Analytic});
        r.set_factorization(one);
        const double p1 = masked_psnr(r.render(cam, light, factorized), analytic);
        r.set_factorization(all);
        const double pk = masked_psnr(r.render(cam, light, factorized), analytic);
        r.set_factorization(mirrored);
        const double pm = masked_psnr(r.render(cam, light, factorized), analytic);
        r.set_factorization(mirrored_as_plain); // looked up as if plain
        const double pw = masked_psnr(r.render(cam, light, factorized), analytic);
        r.set_factorization(warped);
        const double pwa = masked_psnr(r.render(cam, light, factorized), analytic);
        r.set_factorization(warped_as_mirrored); // no warp, no radial factor
        const double pww = masked_psnr(r.render(cam, light, factorized), analytic);
        std::printf("view %d: factorized vs analytic masked PSNR: gshd K = 1 %.2f dB, K = %u %.2f dB; mirrored K = %u "
                    "%.2f dB (looked up as gshd: %.2f dB); warped K = %u %.2f dB (looked up as mirrored: %.2f dB)\n",
                    view, p1, f.term_count(), pk, fm.term_count(), pm, pw, fw.term_count(), pwa, pww);
        worst_one = std::min(worst_one, p1);
        worst_all = std::min(worst_all, pk);
        worst_mirrored = std::min(worst_mirrored, pm);
        worst_wrong = std::min(worst_wrong, pw);
        worst_warped = std::min(worst_warped, pwa);
        worst_warped_wrong = std::min(worst_warped_wrong, pww);
    }
    std::printf("worst view: gshd K = 1 %.2f dB, K = %u %.2f dB (%s); mirrored K = %u %.2f dB (%s)\n", worst_one,
                f.term_count(), worst_all, f.terms.reason.c_str(), fm.term_count(), worst_mirrored,
                fm.param_choice.reason.c_str());
    EXPECT_GE(f.term_count(), 2u);
    EXPECT_GE(worst_all, worst_one + 5.0);
    EXPECT_GE(worst_all, 38.0);
    EXPECT_GE(worst_mirrored, worst_all + 15.0);
    EXPECT_GE(worst_mirrored, 55.0);
    EXPECT_LT(worst_wrong, worst_one); // the renderer must apply the bundle's parametrization
    std::printf("worst view: warped K = %u %.2f dB (%s)\n", fw.term_count(), worst_warped, fw.resolution.reason.c_str());
    EXPECT_GE(worst_warped, worst_mirrored + 10.0);
    EXPECT_GE(worst_warped, 70.0);
    EXPECT_LT(worst_warped_wrong, worst_one);
}

// One warp shared by the channels (kSharedWarp: one pair of coordinates, every channel of each
// lookup) for a lobe whose channels' warps differ a little (knot_hd's fit): the factorized render
// tracks the analytic one on the can, a little below the exact warp per channel (its 6 lookups).
// Measured over the 5 views: 54.8 to 58.6 dB with one warp, 72.4 to 75.2 dB with a warp each.
TEST_F(RenderTest, SharedWarpTracksAnalytic) {
    const synth::Preset preset = synth::make_preset("can");
    const LafortuneRgb lobe{{-1.0213f, -1.0105f, -0.9771f}, {0.9515f, 0.9702f, 0.9683f}, {14.2f, 14.7f, 15.0f}};
    const factorization::Factorization shared = factorization::factorize_cpu(lobe, {});
    const factorization::Factorization per = factorization::factorize_cpu(lobe, {.shared_warp = false});
    ASSERT_TRUE(is_shared_warp(shared.cubes.warp)) << shared.param_choice.reason;
    ASSERT_FALSE(is_shared_warp(per.cubes.warp));
    const SceneData data = constant_albedo(preset.mesh, preset.material.albedo_value);
    Renderer r(ctx(), data.scene(lobe));
    double worst_shared = 999.0, worst_per = 999.0;
    for (int view = 0; view < 5; ++view) {
        const auto [cam, light] = can_view(view);
        const Settings factorized{.specular = SpecularPath::Factorized, .passes = Passes::Deferred};
        const Frame analytic = r.render(cam, light, {.passes = Passes::Deferred});
        r.set_factorization(shared.cubes);
        const double ps = masked_psnr(r.render(cam, light, factorized), analytic);
        r.set_factorization(per.cubes);
        const double pp = masked_psnr(r.render(cam, light, factorized), analytic);
        std::printf("view %d: factorized vs analytic masked PSNR: one warp %.2f dB, a warp per channel %.2f dB\n", view, ps, pp);
        worst_shared = std::min(worst_shared, ps);
        worst_per = std::min(worst_per, pp);
    }
    EXPECT_GE(worst_per, 70.0);
    EXPECT_GE(worst_shared, 50.0);
    EXPECT_LT(worst_shared, worst_per);
}

/// An 8 x 8 cube-map whose float i (texel i / 3, channel i % 3) is base + scale ((i mult) mod m) / m.
CubeMap varied_cube(std::size_t mult, std::size_t m, float base, float scale) {
    CubeMap c{8, std::vector<glm::vec3>(6 * 8 * 8)};
    for (std::size_t i = 0; i < 3 * c.texels.size(); ++i)
        c.texels[i / 3][static_cast<int>(i % 3)] = base + scale * static_cast<float>((i * mult) % m) / static_cast<float>(m);
    return c;
}

/// Passes::Fused sums the same two terms (render/terms.glsl) in one fragment shader that
/// the separate passes add in the blend unit: the same coverage, and colours equal up to
/// float rounding (the two shaders are compiled separately, so the compiler may contract
/// or reorder differently: 1e-5 relative), in both specular models.
TEST_F(RenderTest, FusedPassMatchesTheTwoPasses) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.4f, 0.5f, 0.6f));
    const Camera cam = make_camera(96, 96, 100.0, 100.0, 48.0, 48.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const PointLight light{{2.0, 2.0, 3.0}, {20.0, 20.0, 20.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const CubeMap g = varied_cube(7919, 97, 0.2f, 0.6f), h = varied_cube(104729, 89, 0.1f, 0.8f); // lookups must agree
    for (const FactorParam param : {FactorParam::Gshd, FactorParam::Mirrored})
    for (const SpecularPath model : {SpecularPath::Analytic, SpecularPath::Factorized}) {
        r.set_factorization({.param = param, .terms = {{g, h}}}); // varied texels: the parametrization changes the lookups
        EXPECT_EQ(r.factorization_param(), param);
        const Frame two = r.render(cam, light, {.mode = Mode::Both, .specular = model});
        const Frame one = r.render(cam, light, {.mode = Mode::Both, .specular = model, .passes = Passes::Fused});
        EXPECT_FALSE(two.info.fused);
        EXPECT_TRUE(one.info.fused);
        EXPECT_TRUE(one.info.specular_pass);
        EXPECT_FALSE(one.info.specular_gpu_ms.has_value());
        EXPECT_GT(one.info.covered_pixels, 500u);
        EXPECT_EQ(one.mask, two.mask);
        float max_rel = 0.0f;
        for (std::size_t i = 0; i < one.color.pixels.size(); ++i)
            max_rel = std::max(max_rel, std::abs(one.color.pixels[i] - two.color.pixels[i]) /
                                            std::max(1e-3f, std::abs(two.color.pixels[i])));
        EXPECT_LE(max_rel, 1e-5f) << specular_path_name(model) << " " << to_string(param);
    }
    // Fused changes nothing outside Mode::Both.
    const Frame d1 = r.render(cam, light, {.mode = Mode::Diffuse, .passes = Passes::Fused});
    const Frame d2 = r.render(cam, light, {.mode = Mode::Diffuse});
    EXPECT_FALSE(d1.info.fused);
    EXPECT_EQ(d1.color.pixels, d2.color.pixels);
}

/// The knot with an atlas that varies per texel, its triangles' corners spread over it: the
/// atlas coordinates must come through whatever path a pass takes.
SceneData knot_with_varied_atlas(const synth::Preset& preset) {
    SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    data.albedo = Image(16, 16, 3);
    for (std::size_t i = 0; i < data.albedo.pixels.size(); ++i)
        data.albedo.pixels[i] = 0.1f + 0.8f * static_cast<float>((i * 7919) % 101) / 101.0f;
    for (std::size_t k = 0; k < data.corner_uv.size(); ++k)
        data.corner_uv[k] = glm::vec2(0.03f + 0.94f * static_cast<float>((k * 37) % 61) / 61.0f,
                                      0.03f + 0.94f * static_cast<float>((k * 53) % 67) / 67.0f);
    return data;
}

/// The deferred pass (G-buffer, then one shading draw per pixel) computes the same terms
/// from the same interpolated inputs as the forward passes, in every mode and both
/// specular models, with shadows: the same coverage and colours equal up to float
/// rounding (separately compiled shaders: 1e-5 relative). The atlas varies per texel and
/// the corners spread over it, so the atlas coordinates must come through the G-buffer.
TEST_F(RenderTest, DeferredPassMatchesTheForwardPasses) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = knot_with_varied_atlas(preset);
    const Camera cam = make_camera(96, 80, 100.0, 100.0, 48.0, 40.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const PointLight light{{2.0, 2.0, 3.0}, {20.0, 20.0, 20.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const CubeMap g = varied_cube(7919, 97, 0.2f, 0.6f), h = varied_cube(104729, 89, 0.1f, 0.8f);
    for (const FactorParam param : {FactorParam::Mirrored, FactorParam::Gshd})
    for (const Mode mode : {Mode::Both, Mode::Diffuse, Mode::Specular})
        for (const SpecularPath model : {SpecularPath::Analytic, SpecularPath::Factorized}) {
            if (param == FactorParam::Mirrored && model == SpecularPath::Analytic) continue;
            r.set_factorization({.param = param, .terms = {{g, h}}}); // the last one (Gshd) stays for the checks below
            const Settings forward{.mode = mode, .specular = model};
            Settings deferred = forward;
            deferred.passes = Passes::Deferred;
            const Frame a = r.render(cam, light, forward);
            const Frame b = r.render(cam, light, deferred);
            const std::string what = std::string(mode_name(mode)) + "/" + specular_path_name(model) + "/" + to_string(param);
            EXPECT_TRUE(b.info.deferred) << what;
            EXPECT_FALSE(a.info.deferred) << what;
            EXPECT_TRUE(b.info.shadow_pass) << what;
            EXPECT_EQ(a.info.specular_pass, b.info.specular_pass) << what;
            EXPECT_GT(b.info.covered_pixels, 500u) << what;
            EXPECT_EQ(a.mask, b.mask) << what;
            float max_rel = 0.0f;
            double sum = 0.0;
            for (std::size_t i = 0; i < a.color.pixels.size(); ++i) {
                max_rel = std::max(max_rel, std::abs(a.color.pixels[i] - b.color.pixels[i]) /
                                                std::max(1e-3f, std::abs(a.color.pixels[i])));
                sum += b.color.pixels[i];
            }
            EXPECT_LE(max_rel, 1e-5f) << what;
            EXPECT_GT(sum, 1.0) << what; // something was drawn
        }
    // The viewer draws into its own targets: the deferred sets follow the target in use.
    gpu::RenderTarget other(ctx(), 96, 80, "second target");
    const Settings deferred{.passes = Passes::Deferred};
    const Frame before = r.render(cam, light, deferred);
    gpu::Sequence seq(ctx(), 4);
    seq.record([&](VkCommandBuffer cmd) {
        (void)r.record(cmd, other, cam, light, deferred);
        other.record_readback(cmd);
    });
    seq.submit_and_wait();
    const std::vector<glm::vec4> rgba = other.read_color();
    ASSERT_EQ(rgba.size() * 3, before.color.pixels.size());
    for (std::size_t i = 0; i < rgba.size(); ++i)
        for (int c = 0; c < 3; ++c) ASSERT_EQ(rgba[i][c], before.color.pixels[3 * i + c]) << "pixel " << i;
    const Frame after = r.render(cam, light, deferred); // back to the renderer's own target
    EXPECT_EQ(after.color.pixels, before.color.pixels);
}

/// The deferred shading pass runs only on the pixels the mesh can cover (FrameInfo::drawn,
/// a scissor box): a knot small in the frame, one cut by the frame's edge, and one seen from so
/// near that its bounds reach behind the camera (the whole target) shade the same pixels as the
/// forward passes, with and without cluster culling.
TEST_F(RenderTest, DeferredShadingRunsWhereTheMeshCanBe) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f, 0.4f, 0.3f));
    Renderer whole(ctx(), data.scene(preset.material.lobe));
    Renderer clustered(ctx(), data.scene(preset.material.lobe), {.cluster_culling = true});
    ASSERT_TRUE(clustered.culls_back_faces());
    const PointLight light{{2.2, 3.0, 2.0}, {30.0, 30.0, 30.0}};
    struct View {
        const char* what;
        Camera cam;
        double max_shaded; // of the target's pixels
    };
    const std::array views{
        View{"small", make_camera(160, 120, 100.0, 100.0, 80.0, 60.0, {1.0, 2.0, 9.0}, {0, 0, 0}), 0.3},
        View{"cut by the edge", make_camera(160, 120, 100.0, 100.0, 10.0, 20.0, {1.0, 2.0, 7.0}, {0, 0, 0}), 0.5},
        View{"bounds behind the camera", make_camera(160, 120, 100.0, 100.0, 80.0, 60.0, {0.2, 0.3, 1.05}, {0, 0, 0}), 1.0}};
    for (const View& v : views)
        for (Renderer* r : {&whole, &clustered}) {
            const std::string what = std::string(v.what) + (r == &clustered ? ", clusters" : "");
            const Frame forward = r->render(v.cam, light, {.passes = Passes::Separate});
            const Frame deferred = r->render(v.cam, light, {.passes = Passes::Deferred});
            const std::size_t pixels = 160 * 120;
            const auto shaded = static_cast<std::size_t>(deferred.info.drawn.area());
            EXPECT_GT(forward.info.covered_pixels, 100u) << what;
            EXPECT_GE(shaded, deferred.info.covered_pixels) << what;
            EXPECT_LE(static_cast<double>(shaded), v.max_shaded * pixels) << what;
            if (v.max_shaded == 1.0) {
                EXPECT_EQ(shaded, pixels) << what;
            }
            EXPECT_EQ(forward.info.drawn, deferred.info.drawn) << what; // no pass writes outside it
            EXPECT_EQ(forward.mask, deferred.mask) << what;
            float max_rel = 0.0f;
            for (std::size_t i = 0; i < forward.color.pixels.size(); ++i)
                max_rel = std::max(max_rel, std::abs(forward.color.pixels[i] - deferred.color.pixels[i]) /
                                                std::max(1e-3f, std::abs(forward.color.pixels[i])));
            EXPECT_LE(max_rel, 1e-5f) << what;
        }
}

/// A view's lights pay for its G-buffer once: a deferred frame whose camera and level of detail
/// are the previous deferred frame's shades from the G-buffer that frame left (FrameInfo::
/// gbuffer_kept), with the same pixels, bit for bit, as a renderer that draws it afresh, in every
/// mode, with shadows or without, after forward frames of another camera in between; another
/// camera, near plane or image size draws it again.
TEST_F(RenderTest, DeferredFramesOfOneCameraShadeFromOneGbuffer) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = knot_with_varied_atlas(preset);
    const Camera cam = make_camera(96, 80, 100.0, 100.0, 48.0, 40.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const Camera other_cam = make_camera(96, 80, 100.0, 100.0, 48.0, 40.0, {-2.0, 1.5, 3.5}, {0, 0, 0});
    const std::array<PointLight, 3> lights = {PointLight{{2.0, 2.0, 3.0}, {20.0, 20.0, 20.0}},
                                              PointLight{{-2.5, 1.0, 2.5}, {15.0, 18.0, 20.0}},
                                              PointLight{{0.5, -2.0, 3.5}, {25.0, 20.0, 15.0}}};
    const Scene scene = data.scene(preset.material.lobe);
    Renderer r(ctx(), scene), ref(ctx(), scene);
    // The reference draws its G-buffer afresh: a frame of a third camera comes first.
    const Camera third = make_camera(96, 80, 90.0, 90.0, 48.0, 40.0, {3.0, -1.0, 3.0}, {0, 0, 0});
    const auto fresh = [&](const Camera& c, const PointLight& l, const Settings& s) {
        (void)ref.render(third, l, s);
        const Frame f = ref.render(c, l, s);
        EXPECT_FALSE(f.info.gbuffer_kept);
        return f;
    };
    const auto expect_same = [](const Frame& a, const Frame& b, const std::string& what) {
        EXPECT_EQ(a.mask, b.mask) << what;
        EXPECT_EQ(a.color.pixels, b.color.pixels) << what;
        EXPECT_GT(a.info.covered_pixels, 500u) << what;
    };
    for (const bool shadows : {true, false})
        for (const Mode mode : {Mode::Both, Mode::Diffuse, Mode::Specular}) {
            const Settings s{.mode = mode, .passes = Passes::Deferred, .shadows = shadows};
            const std::string what = std::string(mode_name(mode)) + (shadows ? "/shadows" : "/no shadows");
            for (std::size_t l = 0; l < lights.size(); ++l) {
                const Frame f = r.render(cam, lights[l], s);
                // Only the very first frame of the renderer draws the G-buffer: every later one
                // has the same camera, whatever the mode, the light or the shadows.
                EXPECT_EQ(f.info.gbuffer_kept, shadows == false || mode != Mode::Both || l > 0) << what << " light " << l;
                expect_same(f, fresh(cam, lights[l], s), what + " light " + std::to_string(l));
            }
        }
    const Settings deferred{.passes = Passes::Deferred};
    // Forward frames of another camera leave the G-buffer alone (they write the colour and depth).
    const Frame forward = r.render(other_cam, lights[0], {.passes = Passes::Fused});
    EXPECT_FALSE(forward.info.gbuffer_kept);
    const Frame again = r.render(cam, lights[1], deferred);
    EXPECT_TRUE(again.info.gbuffer_kept);
    expect_same(again, fresh(cam, lights[1], deferred), "after a forward frame of another camera");
    // Another camera, near plane or image size: the G-buffer is drawn again.
    const Frame moved = r.render(other_cam, lights[1], deferred);
    EXPECT_FALSE(moved.info.gbuffer_kept);
    expect_same(moved, fresh(other_cam, lights[1], deferred), "another camera");
    const Frame back = r.render(cam, lights[1], deferred);
    EXPECT_FALSE(back.info.gbuffer_kept);
    expect_same(back, again, "back to the first camera");
    Settings nearer = deferred;
    nearer.near = 0.5;
    const Frame near_frame = r.render(cam, lights[1], nearer);
    EXPECT_FALSE(near_frame.info.gbuffer_kept);
    EXPECT_TRUE(r.render(cam, lights[2], nearer).info.gbuffer_kept);
    const Camera larger = make_camera(120, 100, 125.0, 125.0, 60.0, 50.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const Frame resized = r.render(larger, lights[2], deferred);
    EXPECT_FALSE(resized.info.gbuffer_kept);
    expect_same(resized, fresh(larger, lights[2], deferred), "another image size");
}

TEST_F(RenderTest, TwoRendersAreIdentical) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    const Camera cam = make_camera(96, 96, 100.0, 100.0, 48.0, 48.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const PointLight light{{2.0, 2.0, 3.0}, {20.0, 20.0, 20.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const Frame a = r.render(cam, light);
    const Frame b = r.render(cam, light);
    Renderer r2(ctx(), data.scene(preset.material.lobe));
    const Frame c = r2.render(cam, light);
    EXPECT_GT(a.info.covered_pixels, 500u);
    EXPECT_EQ(0, std::memcmp(a.color.pixels.data(), b.color.pixels.data(), a.color.pixels.size() * sizeof(float)));
    EXPECT_EQ(0, std::memcmp(a.color.pixels.data(), c.color.pixels.data(), a.color.pixels.size() * sizeof(float)));
    EXPECT_EQ(a.mask, b.mask);
    EXPECT_EQ(a.mask, c.mask);
}

TEST_F(RenderTest, ResizesToEachCameraAndRefusesBadInputs) {
    const synth::Preset preset = synth::make_preset("sphere");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    Renderer r(ctx(), data.scene());
    const PointLight light{{1.0, 1.5, 2.0}, {4.0, 4.0, 4.0}};
    const Frame small = r.render(make_camera(32, 24, 40, 40, 16, 12, {0, 0, 2}, {0, 0, 0}), light);
    const Frame large = r.render(make_camera(80, 60, 100, 100, 40, 30, {0, 0, 2}, {0, 0, 0}), light);
    EXPECT_EQ(small.color.width, 32);
    EXPECT_EQ(small.mask.size(), 32u * 24u);
    EXPECT_EQ(large.color.height, 60);
    EXPECT_GT(large.info.covered_pixels, small.info.covered_pixels);

    SceneData bad = data;
    bad.corner_uv.pop_back();
    EXPECT_THROW(Renderer(ctx(), bad.scene()), Error);
    EXPECT_THROW(Renderer(ctx(), Scene{.mesh = &data.mesh, .corner_uv = data.corner_uv, .albedo = nullptr}), Error);
}

// ---------------------------------------------------------------------------------------------
// The coated family (shared/coated.h): every pass draws the scene's material through
// shared/material.h, the diffuse term times k_d = T(n.u) T(n.v) / T(1)^2 in both specular paths.

CoatedParams coated(float alpha, float eta = 1.5f, glm::vec3 tint = glm::vec3(1.0f)) {
    return CoatedParams{.eta = eta, .alpha = alpha, .tint = tint};
}

/// What a pixel of a flat, uniformly lit-and-shaded scene should show, from the C++ (double)
/// evaluation of the same definitions: the point where the pixel centre's ray meets the plane
/// (point `p0`, unit normal `n`), then (rho / pi) k_d + f_s (or the factorized f_s `factor`
/// when given) times I max(0, n.u) / d^2.
// A 2x2 square through the origin with the constant normal kTiltedNormal (counter-clockwise about
// it): the renderer's interpolation is exact on it, so a pixel's value has a closed form.
const glm::dvec3 kTiltedNormal = glm::normalize(glm::dvec3(0.25, 0.15, 1.0));
Mesh tilted_quad() {
    const glm::dvec3 n = kTiltedNormal;
    const glm::dvec3 t = glm::normalize(glm::cross(n, glm::dvec3(0, 1, 0))), b = glm::cross(n, t);
    Mesh quad;
    const double corners[4][2] = {{-1.0, -1.0}, {1.0, -1.0}, {1.0, 1.0}, {-1.0, 1.0}};
    for (const auto& c : corners) quad.positions.push_back(glm::vec3(c[0] * t + c[1] * b));
    quad.normals.assign(4, glm::vec3(n));
    quad.triangles = {{0, 1, 2}, {0, 2, 3}};
    if (glm::dot(glm::cross(glm::dvec3(quad.positions[1] - quad.positions[0]), glm::dvec3(quad.positions[2] - quad.positions[0])), n) < 0.0)
        quad.triangles = {{0, 2, 1}, {0, 3, 2}};
    return quad;
}

// The tilted plane's scene: a constant albedo, a camera looking at it and a light near it.
struct TiltedPlane {
    glm::dvec3 rho{0.55, 0.4, 0.3};
    SceneData data = constant_albedo(tilted_quad(), glm::vec3(rho));
    Camera camera = make_camera(64, 64, 56.0, 56.0, 32.0, 32.0, {0.1, -0.2, 3.0}, {0, 0, 0});
    PointLight light{{0.9, 0.3, 2.6}, {5.0, 4.5, 4.0}};
};

glm::dvec3 direct_pixel_of(const Camera& cam, int x, int y, const glm::dvec3& p0, const glm::dvec3& n, const PointLight& light,
                           const glm::dvec3& rho, const shared::MaterialGpu& m, Mode mode, std::optional<glm::dvec3> factor) {
    const Intrinsics& k = cam.intrinsics;
    const glm::dvec3 o = cam.center();
    const glm::dvec3 c((x + 0.5 - k.cx) / k.fl_x, -(y + 0.5 - k.cy) / k.fl_y, -1.0);
    const glm::dvec3 dir = glm::normalize(glm::dvec3(cam.camera_to_world * glm::dvec4(c, 0.0)));
    const glm::dvec3 p = o + dir * (glm::dot(p0 - o, n) / glm::dot(dir, n));
    const glm::dvec3 to_light = light.position - p;
    const double d2 = glm::dot(to_light, to_light);
    const glm::dvec3 u = to_light / std::sqrt(d2), v = glm::normalize(o - p);
    const double ci = glm::dot(n, u), co = glm::dot(n, v);
    const glm::dvec3 irradiance = light.intensity * (std::max(ci, 0.0) / d2);
    glm::dvec3 f(0.0);
    if (mode != Mode::Specular) f += rho / kPi * shared::f64::material_diffuse_factor_uv(m, ci, co, glm::dot(u, v));
    if (mode != Mode::Diffuse) f += factor ? *factor : shared::f64::material_specular(m, ci, co, glm::dot(u, v));
    return f * irradiance;
}

glm::dvec3 direct_pixel(const Camera& cam, int x, int y, const glm::dvec3& p0, const glm::dvec3& n, const PointLight& light,
                        const glm::dvec3& rho, const SpecularModel& model, Mode mode, std::optional<glm::dvec3> factor) {
    return direct_pixel_of(cam, x, y, p0, n, light, rho, material_gpu(model), mode, factor);
}

// The analytic render of a coated material equals the direct C++ evaluation of the model at
// every interior pixel of a tilted plane (constant normal, so the renderer's interpolation is
// exact), in every mode and pass arrangement; the factorized path (constant cube-maps G = a,
// H = b: f_s = a b) too, its diffuse term with the coating's k_d. Tolerance: float against
// double, 2e-4 relative plus 1e-5 of the frame's peak (measured: 2e-5 relative at most; the
// sharp lobe's slope, 4 theta / alpha^2 per radian, over float's direction error is below it).
// A lafortune model of zero lobe draws the plain Lambertian term (k_d = 1), which differs.
TEST_F(RenderTest, CoatedAnalyticMatchesDirectEvaluation) {
    const TiltedPlane plane;
    const glm::dvec3& n = kTiltedNormal;
    const glm::dvec3& rho = plane.rho;
    const SceneData& data = plane.data;
    const Camera& cam = plane.camera;
    const PointLight& light = plane.light;
    const glm::vec3 a(0.3f, 0.5f, 0.7f), bb(0.9f, 0.4f, 0.2f);
    for (const CoatedParams& model : {coated(0.12f), coated(0.4f, 2.0f, {0.9f, 0.7f, 0.5f})}) {
        Renderer r(ctx(), data.scene(model));
        EXPECT_TRUE(r.has_specular());
        EXPECT_EQ(r.material().family.x, shared::kMaterialCoated);
        r.set_factorization(FactorizedSpecular{.param = FactorParam::Gshd, .terms = {{constant_cube(8, a), constant_cube(8, bb)}}});
        double worst = 0.0;
        std::size_t compared = 0;
        for (const SpecularPath path : {SpecularPath::Analytic, SpecularPath::Factorized})
            for (const Mode mode : {Mode::Both, Mode::Diffuse, Mode::Specular})
                for (const Passes passes : {Passes::Separate, Passes::Fused, Passes::Deferred}) {
                    const Frame f = r.render(cam, light, {.mode = mode, .specular = path, .passes = passes, .shadows = false});
                    const std::string what = std::string(mode_name(mode)) + "/" + specular_path_name(path) + "/" + passes_name(passes);
                    const std::optional<glm::dvec3> factor =
                        path == SpecularPath::Factorized ? std::optional(glm::dvec3(a * bb)) : std::nullopt;
                    double peak = 0.0;
                    for (const float x : f.color.pixels) peak = std::max(peak, static_cast<double>(x));
                    ASSERT_GT(peak, 0.0) << what;
                    for (int y = 0; y < 64; ++y)
                        for (int x = 0; x < 64; ++x) {
                            if (!interior(f.mask, 64, 64, x, y)) continue;
                            const glm::dvec3 e = direct_pixel(cam, x, y, glm::dvec3(0.0), n, light, rho, model, mode, factor);
                            for (int c = 0; c < 3; ++c) {
                                const double got = f.color.at(x, y, c), err = std::abs(got - e[c]);
                                worst = std::max(worst, err / (std::abs(e[c]) + 0.05 * peak));
                                ASSERT_LE(err, 2e-4 * std::abs(e[c]) + 1e-5 * peak)
                                    << what << " alpha " << model.alpha << " pixel (" << x << ", " << y << ") channel " << c
                                    << ": " << got << " vs " << e[c];
                            }
                            ++compared;
                        }
                }
        EXPECT_GT(compared, 18u * 1000u);
        std::printf("coated alpha %.2f: %zu pixel comparisons, worst relative error %.3g\n", model.alpha, compared, worst);
        // The coating's k_d is there: the Lambertian term of the zero lobe is brighter at grazing
        // and darker nowhere (T(c) <= T(1)).
        const Frame coated_diffuse = r.render(cam, light, {.mode = Mode::Diffuse, .shadows = false});
        r.set_specular(LafortuneRgb{});
        const Frame lambert = r.render(cam, light, {.mode = Mode::Diffuse, .shadows = false});
        double lower = 0.0;
        for (std::size_t i = 0; i < lambert.color.pixels.size(); ++i) {
            EXPECT_LE(coated_diffuse.color.pixels[i], lambert.color.pixels[i] * (1.0f + 1e-5f) + 1e-9f);
            lower = std::max(lower, static_cast<double>(lambert.color.pixels[i] - coated_diffuse.color.pixels[i]));
        }
        EXPECT_GT(lower, 0.0);
    }
}

// glTF's core material drawn instead of the model (Renderer::set_material: what ordinary viewers
// show) equals the direct evaluation of shared/gltf_core.h on a tilted plane, base layer and
// clearcoat, in every mode and pass arrangement (the same tolerance as the coated family's); the
// factorized path is refused.
TEST_F(RenderTest, CoreMaterialMatchesDirectEvaluation) {
    const TiltedPlane plane;
    const glm::dvec3& n = kTiltedNormal;
    const glm::dvec3& rho = plane.rho;
    const SceneData& data = plane.data;
    const Camera& cam = plane.camera;
    const PointLight& light = plane.light;
    Renderer r(ctx(), data.scene(LafortuneRgb{}));
    for (const CoreMaterial& core : {CoreMaterial{.roughness = 0.4, .f0 = 0.05, .f90 = 0.8},
                                     CoreMaterial{.roughness = 1.0, .clearcoat = 0.9, .clearcoat_roughness = 0.3}}) {
        const shared::MaterialGpu m = core_material_gpu(core);
        r.set_material(m, core.has_specular());
        EXPECT_TRUE(r.has_specular());
        double worst = 0.0;
        for (const Mode mode : {Mode::Both, Mode::Diffuse, Mode::Specular})
            for (const Passes passes : {Passes::Separate, Passes::Fused, Passes::Deferred}) {
                const Frame f = r.render(cam, light, {.mode = mode, .passes = passes, .shadows = false});
                const std::string what = std::string(mode_name(mode)) + "/" + passes_name(passes);
                double peak = 0.0;
                for (const float x : f.color.pixels) peak = std::max(peak, static_cast<double>(x));
                ASSERT_GT(peak, 0.0) << what;
                for (int y = 0; y < 64; ++y)
                    for (int x = 0; x < 64; ++x) {
                        if (!interior(f.mask, 64, 64, x, y)) continue;
                        const glm::dvec3 e = direct_pixel_of(cam, x, y, glm::dvec3(0.0), n, light, rho, m, mode, std::nullopt);
                        for (int c = 0; c < 3; ++c) {
                            const double got = f.color.pixels[(static_cast<std::size_t>(y) * 64 + x) * 3 + c];
                            worst = std::max(worst, std::abs(got - e[c]) / (2e-4 * std::abs(e[c]) + 1e-5 * peak));
                        }
                    }
            }
        EXPECT_LE(worst, 1.0) << "roughness " << core.roughness << ", clearcoat " << core.clearcoat;
        EXPECT_THROW((void)r.render(cam, light, {.specular = SpecularPath::Factorized}), Error);
    }
    r.set_specular(LafortuneRgb{}); // ends the override: a zero lobe draws no specular
    EXPECT_FALSE(r.has_specular());
}

// The indexed mesh reproduces every triangle's corners exactly (position, normal, atlas
// coordinate) with fewer vertices than corners; a PassClock marks each deferred pass.
TEST_F(RenderTest, IndexedVerticesReproduceTheCornersAndPassesAreTimed) {
    const synth::Preset preset = synth::make_preset("knot");
    SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    const Mesh& mesh = preset.mesh;
    const IndexedVertices iv = index_vertices(mesh, data.corner_uv);
    ASSERT_EQ(iv.indices.size(), 3 * mesh.triangles.size());
    EXPECT_LT(iv.vertices.size(), iv.indices.size() / 2);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const shared::RenderVertex& v = iv.vertices.at(iv.indices[3 * t + k]);
            const uint32_t p = mesh.triangles[t][k];
            const glm::vec2 uv = data.corner_uv[3 * t + k];
            ASSERT_EQ(glm::vec3(v.position_u), mesh.positions[p]) << t;
            ASSERT_EQ(v.position_u.w, uv.x) << t;
            ASSERT_EQ(v.normal_v.w, uv.y) << t;
            ASSERT_EQ(glm::vec3(v.normal_v), glm::normalize(mesh.normals[p])) << t;
        }
    Renderer r(ctx(), data.scene(preset.material.lobe));
    const Camera cam = make_camera(96, 80, 100.0, 100.0, 48.0, 40.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const PointLight light{{2.0, 2.0, 3.0}, {20.0, 20.0, 20.0}};
    gpu::RenderTarget target(ctx(), 96, 80, "timed target");
    gpu::PassClock clock(ctx());
    gpu::Sequence seq(ctx(), 1);
    seq.record([&](VkCommandBuffer cmd) {
        clock.start(cmd);
        (void)r.record(cmd, target, cam, light, {.passes = Passes::Deferred, .shadows = true}, &clock);
    });
    seq.submit_and_wait();
    const auto marks = clock.read();
    if (!clock.available()) GTEST_SKIP() << "no timestamps on this device";
    ASSERT_EQ(marks.size(), 3u);
    EXPECT_EQ(marks[0].first, "shadow map");
    EXPECT_EQ(marks[1].first, "g-buffer");
    EXPECT_EQ(marks[2].first, "shading");
    for (const auto& [label, ms] : marks) {
        EXPECT_GE(ms, 0.0) << label;
        EXPECT_LT(ms, 10000.0) << label;
    }
}

// A warped factorization multiplies by the Lafortune lobe's radial factor: a coated model does
// not have it, so the renderer refuses the pair (at set_factorization, or at a factorized render
// when the model changes after it), and draws the analytic path still.
TEST_F(RenderTest, WarpedFactorizationNeedsALafortuneModel) {
    const synth::Preset preset = synth::make_preset("sphere");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    const CubeMap cube{8, std::vector<glm::vec3>(6 * 8 * 8, glm::vec3(0.5f))};
    const FactorizedSpecular warped{.param = FactorParam::Warped, .warp = glm::vec4(-1.0f, 0.8f, 0.8f, 0.8f), .terms = {{cube, cube}}};
    Renderer coated_renderer(ctx(), data.scene(coated(0.2f)));
    EXPECT_THROW(coated_renderer.set_factorization(warped), Error);
    EXPECT_FALSE(coated_renderer.has_factorization());
    Renderer r(ctx(), data.scene(preset.material.lobe));
    r.set_factorization(warped);
    const Camera cam = make_camera(32, 32, 40.0, 40.0, 16.0, 16.0, {0.0, 0.0, 2.0}, {0, 0, 0});
    const PointLight light{{1.0, 1.0, 2.0}, {3.0, 3.0, 3.0}};
    EXPECT_NO_THROW((void)r.render(cam, light, {.specular = SpecularPath::Factorized}));
    r.set_specular(coated(0.2f));
    EXPECT_THROW((void)r.render(cam, light, {.specular = SpecularPath::Factorized}), Error);
    const Frame analytic = r.render(cam, light, {.specular = SpecularPath::Analytic});
    EXPECT_TRUE(analytic.info.specular_pass);
    r.set_specular(coated(0.2f, 1.5f, glm::vec3(0.0f))); // zero tint: no specular pass, nothing refused
    const Frame none = r.render(cam, light, {.specular = SpecularPath::Factorized});
    EXPECT_FALSE(none.info.specular_pass);
    EXPECT_NE(none.info.specular_note.find("no lobe"), std::string::npos);
}

// Issue 5's criterion for the coated family: the factorized render within 1 dB of the analytic
// one. As for the can's lobe above, within 1 dB of the analytic render's masked PSNR against a
// capture needs PSNR(factorized vs analytic) >= PSNR(analytic vs capture) + 5.9 dB; with the
// can's figures (41.7 dB train, 33.5 dB test) that is >= 47.6 dB on average over the frames and
// >= 39.4 dB on every frame, asserted here on the synth presets' meshes (can, cologne, vase,
// woodenpot, knot; constant albedo) for eta 1.5 and alpha 0.05, 0.12, 0.25, 0.4, with the
// factorization's default grids, K and weight in the plain GSHD (the automatic choice's, tested
// in tests/factorization CoatedFamily; its mirrored run would double the time), over the frames of
// the spread rig (`specula synth`'s: lights 15 to 130 degrees off the camera) and of the thesis's
// ring (six lights about 15 degrees around the camera), a train view and a test view each (16
// frames), unshadowed (the same shadow map darkens both paths alike).
TEST_F(RenderTest, CoatedFactorizedWithinOneDbOfAnalyticOnThePresets) {
    std::vector<synth::Preset> presets;
    for (const char* name : {"can", "cologne", "vase", "woodenpot", "knot"}) presets.push_back(synth::make_preset(name));
    for (const float alpha : {0.05f, 0.12f, 0.25f, 0.4f}) {
        const CoatedParams model = coated(alpha);
        const Stopwatch clock;
        const factorization::Factorization f = factorization::factorize_cpu(model, {.param = FactorParam::Gshd});
        const double seconds = clock.seconds();
        std::printf("alpha %.2f: %s, %u x %u, K = %u, weight q = %.2f, factorized in %.1f s (CPU)\n  %s\n", alpha,
                    to_string(f.cubes.param), f.resolution.grid_h, f.resolution.grid_d, f.term_count(),
                    static_cast<double>(f.weight_q), seconds, f.terms.reason.c_str());
        for (const synth::Preset& p : presets) {
            const SceneData data = constant_albedo(p.mesh, glm::vec3(0.45f, 0.4f, 0.35f));
            Renderer r(ctx(), data.scene(model), {.shadow_map_size = 16}); // unused: unshadowed
            r.set_factorization(f.cubes);
            double worst = 999.0, sum = 0.0;
            std::size_t frames = 0;
            for (const bool ring : {false, true}) {
                synth::RigOptions o;
                o.size = 128;
                o.views = 1;
                o.test_views = 1;
                if (ring) o.light_angles_deg.clear(); // the thesis's ring about 15 degrees around the camera
                for (const synth::RigView& view : synth::make_rig(p.mesh, o).views)
                    for (const PointLight& light : view.lights) {
                        const Frame an = r.render(view.camera, light, {.specular = SpecularPath::Analytic, .shadows = false});
                        const Frame fa = r.render(view.camera, light, {.specular = SpecularPath::Factorized, .shadows = false});
                        const double psnr = masked_psnr(fa, an);
                        worst = std::min(worst, psnr);
                        sum += psnr;
                        ++frames;
                    }
            }
            const double mean = sum / static_cast<double>(frames);
            std::printf("  %-9s factorized vs analytic masked PSNR over %zu frames: mean %.1f dB, worst %.1f dB\n",
                        p.name.c_str(), frames, mean, worst);
            EXPECT_GE(mean, 47.6) << p.name << " alpha " << alpha;
            EXPECT_GE(worst, 39.4) << p.name << " alpha " << alpha;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The lit passes' specialization constants (term count, parametrization, material family,
// shadows: render/terms.glsl) and the levels of detail.

/// Display PSNR (sRGB 8-bit codes, peak 1) of `a` against `b` over the pixels either covers, as
/// Renderer::accept_levels_of_detail scores a level; `b` a Frame or synth's RenderedFrame.
template <class Other>
double display_psnr_where_either_covers(const Frame& a, const Other& b) {
    const auto code = [](float v) { return std::round(255.0 * linear_to_srgb(std::clamp(v, 0.0f, 1.0f))); };
    double se = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < a.mask.size(); ++i) {
        if (!a.mask[i] && !b.mask[i]) continue;
        for (std::size_t c = 0; c < 3; ++c) {
            const double d = (code(a.color.pixels[3 * i + c]) - code(b.color.pixels[3 * i + c])) / 255.0;
            se += d * d;
        }
        n += 3;
    }
    return 10.0 * std::log10(static_cast<double>(n) / se);
}

/// Bit-exact equality of two frames' colours and masks.
void expect_same_frame(const Frame& a, const Frame& b, const std::string& what) {
    EXPECT_EQ(a.mask, b.mask) << what;
    ASSERT_EQ(a.color.pixels.size(), b.color.pixels.size()) << what;
    EXPECT_EQ(0, std::memcmp(a.color.pixels.data(), b.color.pixels.data(), a.color.pixels.size() * sizeof(float))) << what;
}

// A renderer whose frames change the constants (shadows off and on, another material family,
// another term count) builds its pipelines for them, or takes back the ones it parked (shadows
// off again, the lobe again, one term again: their sets then get the current cube-maps), and draws
// exactly what a renderer made for that state draws, in every pass arrangement.
TEST_F(RenderTest, PipelinesFollowEachFramesConstants) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f, 0.4f, 0.3f));
    const Camera cam = make_camera(96, 96, 100.0, 100.0, 48.0, 48.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const PointLight light{{2.2, 3.0, 2.0}, {30.0, 30.0, 30.0}};
    Renderer r(ctx(), data.scene(preset.material.lobe));
    for (const Passes passes : {Passes::Separate, Passes::Fused, Passes::Deferred})
        for (const bool shadows : {false, true, false}) {
            Renderer fresh(ctx(), data.scene(preset.material.lobe));
            const Settings s{.passes = passes, .shadows = shadows};
            expect_same_frame(r.render(cam, light, s), fresh.render(cam, light, s),
                              std::string(passes_name(passes)) + (shadows ? ", shadows" : ", no shadows"));
        }

    const CoreMaterial core{.roughness = 0.4, .f0 = 0.05, .f90 = 0.8, .clearcoat = 0.5, .clearcoat_roughness = 0.2};
    r.set_material(core_material_gpu(core), true);
    Renderer fresh_core(ctx(), data.scene(preset.material.lobe));
    fresh_core.set_material(core_material_gpu(core), true);
    const Settings deferred{.passes = Passes::Deferred};
    const Frame core_frame = r.render(cam, light, deferred);
    expect_same_frame(core_frame, fresh_core.render(cam, light, deferred), "core material");
    r.set_specular(preset.material.lobe); // back to the Lafortune family
    Renderer fresh_lobe(ctx(), data.scene(preset.material.lobe));
    const Frame lobe_frame = r.render(cam, light, deferred);
    expect_same_frame(lobe_frame, fresh_lobe.render(cam, light, deferred), "back to the lobe");
    EXPECT_NE(0, std::memcmp(core_frame.color.pixels.data(), lobe_frame.color.pixels.data(),
                             core_frame.color.pixels.size() * sizeof(float)));

    const FactorTerm t1{constant_cube(8, {0.3f, 0.5f, 0.7f}), constant_cube(8, {0.9f, 0.4f, 0.2f})};
    const FactorTerm t2{constant_cube(8, {0.2f, 0.1f, 0.1f}), constant_cube(8, {0.5f, 0.5f, 0.5f})};
    const Settings factorized{.specular = SpecularPath::Factorized, .passes = Passes::Deferred};
    r.set_factorization(FactorizedSpecular{.terms = {t1, t2}});
    const Frame two = r.render(cam, light, factorized);
    r.set_factorization(FactorizedSpecular{.terms = {t1}});
    Renderer fresh_one(ctx(), data.scene(preset.material.lobe));
    fresh_one.set_factorization(FactorizedSpecular{.terms = {t1}});
    const Frame one = r.render(cam, light, factorized);
    expect_same_frame(one, fresh_one.render(cam, light, factorized), "one term after two");
    EXPECT_NE(0, std::memcmp(one.color.pixels.data(), two.color.pixels.data(), one.color.pixels.size() * sizeof(float)));
}

// Levels of detail of the knot (38,400 triangles): each a range of one index buffer over the same
// vertices, at most 3/4 of the level before, with a growing error; the choice per frame takes the
// coarsest level whose error, projected at the bounding sphere's nearest point, is within bound.
TEST(LevelsOfDetail, HalveTheTrianglesAndAreChosenByProjectedError) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    IndexedVertices mesh = index_vertices(data.mesh, data.corner_uv);
    const std::size_t full = mesh.indices.size();
    const std::vector<LevelOfDetail> levels = build_levels_of_detail(mesh).levels;
    ASSERT_GE(levels.size(), 3u);
    EXPECT_EQ(levels[0].first_index, 0u);
    EXPECT_EQ(levels[0].index_count, full);
    EXPECT_EQ(levels[0].error, 0.0);
    std::size_t end = full;
    for (std::size_t k = 1; k < levels.size(); ++k) {
        EXPECT_EQ(levels[k].first_index, end) << k;
        end += levels[k].index_count;
        EXPECT_EQ(levels[k].index_count % 3, 0u);
        EXPECT_LE(4 * levels[k].index_count, 3 * levels[k - 1].index_count) << k;
        EXPECT_GE(levels[k].index_count / 3, 1000u) << k;
        EXPECT_GT(levels[k].error, 0.0) << k;
        EXPECT_GE(levels[k].error, levels[k - 1].error) << k;
    }
    EXPECT_EQ(end, mesh.indices.size());
    for (const uint32_t i : mesh.indices) ASSERT_LT(i, mesh.vertices.size());

    const Bounds b = mesh_bounds(data.mesh);
    const glm::dvec3 center(b.center());
    const double radius = b.radius();
    const auto level_at = [&](double distance, double max_px) {
        const Camera cam = make_camera(512, 512, 500.0, 500.0, 256.0, 256.0, center + glm::dvec3(0.0, 0.0, distance), center);
        return choose_level_of_detail(levels, cam, center, radius, max_px);
    };
    EXPECT_EQ(level_at(3.0 * radius, 0.0), 0u); // no bound: the whole mesh
    // Within bound exactly where error x focal / (distance - radius) <= max_px.
    for (std::size_t k = 1; k < levels.size(); ++k) {
        const double at = radius + levels[k].error * 500.0 / 0.5; // level k's error is 0.5 px from here
        EXPECT_GE(level_at(1.01 * at, 0.5), k) << k;
        EXPECT_LT(level_at(0.99 * at, 0.5), k) << k;
    }
    EXPECT_EQ(level_at(1e6 * radius, 0.5), levels.size() - 1);
}

// The renderer draws a level when the frame allows it, and accept_levels_of_detail keeps only the
// levels whose renders score at least the bound against the whole mesh's: the score it returns is
// that of the frames it drew.
TEST_F(RenderTest, LevelsOfDetailAreDrawnWhereTheyLookTheSame) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f, 0.4f, 0.3f));
    Renderer r(ctx(), data.scene(preset.material.lobe), {.lod_max_error_px = 0.5});
    Renderer whole(ctx(), data.scene(preset.material.lobe));
    const std::size_t levels = r.levels_of_detail().size();
    ASSERT_GE(levels, 3u);
    EXPECT_EQ(whole.levels_of_detail().size(), 1u);
    EXPECT_EQ(r.accepted_levels_of_detail(), levels);
    const Camera cam = make_camera(128, 128, 130.0, 130.0, 64.0, 64.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const PointLight light{{2.2, 3.0, 2.0}, {30.0, 30.0, 30.0}};
    const Settings s{.passes = Passes::Deferred};
    const Frame coarse = r.render(cam, light, s);
    const Bounds b = mesh_bounds(preset.mesh);
    const std::size_t chosen = coarse.info.lod_level; // without clusters, the frame's one level for every patch
    EXPECT_GE(chosen, 1u);                             // the knot's errors are below a pixel here
    EXPECT_EQ(chosen, choose_level_of_detail(r.levels_of_detail(), cam, glm::dvec3(b.center()), b.radius(), 0.5));
    EXPECT_EQ(coarse.info.triangles, r.levels_of_detail()[chosen].index_count / 3);
    const Frame full = whole.render(cam, light, s);
    EXPECT_EQ(full.info.triangles, preset.mesh.triangles.size());

    const std::vector<Camera> cams{cam};
    const std::vector<PointLight> lights{light};
    const std::vector<double> psnr = r.accept_levels_of_detail(cams, lights, s, 0.0);
    ASSERT_EQ(psnr.size(), levels);
    EXPECT_EQ(r.accepted_levels_of_detail(), levels);
    EXPECT_TRUE(std::isinf(psnr[0]));
    for (std::size_t k = 1; k < levels; ++k) {
        EXPECT_TRUE(std::isfinite(psnr[k])) << k; // a coarser mesh changes some pixels
        EXPECT_GT(psnr[k], 20.0) << k;
    }
    EXPECT_GT(psnr[1], psnr[levels - 1]);
    // The drawn level's score is that of the frame it drew against the whole mesh's.
    EXPECT_NEAR(psnr[chosen], display_psnr_where_either_covers(coarse, full), 1e-9);

    // A bound between the first and the last level's scores keeps the levels before the first
    // under it; a bound no level meets keeps the whole mesh only.
    const double bound = 0.5 * (psnr[1] + psnr[levels - 1]);
    (void)r.accept_levels_of_detail(cams, lights, s, bound);
    std::size_t kept = 1;
    while (kept < levels && psnr[kept] >= bound) ++kept;
    EXPECT_EQ(r.accepted_levels_of_detail(), kept);
    EXPECT_LT(kept, levels);
    EXPECT_EQ(r.render(cam, light, s).info.lod_level, kept - 1);
    (void)r.accept_levels_of_detail(cams, lights, s, 1e9);
    EXPECT_EQ(r.accepted_levels_of_detail(), 1u);
    const Frame again = r.render(cam, light, s);
    EXPECT_EQ(again.info.lod_level, 0u);
    expect_same_frame(again, full, "level 0 is the whole mesh");
    EXPECT_THROW((void)r.accept_levels_of_detail(cams, {}, s, 0.0), Error);
}

// Cluster culling (Options::cluster_culling) draws the same pixels, bit for bit, in every pass
// arrangement, with and without shadows, from a fraction of the triangles; the clusters hold every
// triangle of each level once, and a cluster facing away from the camera holds only back faces.
TEST_F(RenderTest, ClusterCullingDrawsTheSamePixelsFromFewerTriangles) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f, 0.4f, 0.3f));
    Renderer whole(ctx(), data.scene(preset.material.lobe));
    Renderer clustered(ctx(), data.scene(preset.material.lobe), {.cluster_culling = true}); // one level
    ASSERT_TRUE(clustered.culls_back_faces());
    const PointLight light{{2.2, 3.0, 2.0}, {30.0, 30.0, 30.0}};
    for (const glm::dvec3& eye : {glm::dvec3(0.5, 1.0, 4.5), glm::dvec3(-3.0, -2.0, 2.5)}) {
        const Camera cam = make_camera(96, 96, 100.0, 100.0, 48.0, 48.0, eye, {0, 0, 0});
        for (const Passes passes : {Passes::Separate, Passes::Fused, Passes::Deferred})
            for (const bool shadows : {false, true}) {
                const Settings s{.passes = passes, .shadows = shadows};
                const Frame c = clustered.render(cam, light, s);
                const Frame w = whole.render(cam, light, s);
                EXPECT_LT(c.info.triangles, 3 * w.info.triangles / 4);
                EXPECT_EQ(w.info.triangles, preset.mesh.triangles.size());
                expect_same_frame(c, w, std::string(passes_name(passes)) + (shadows ? ", shadows" : ""));
            }
    }

    IndexedVertices mesh = index_vertices(data.mesh, data.corner_uv);
    const std::vector<LevelOfDetail> levels = build_levels_of_detail(mesh).levels;
    const std::vector<uint32_t> before = mesh.indices;
    const std::vector<std::vector<TriangleCluster>> clusters = cluster_levels(mesh, levels);
    ASSERT_EQ(clusters.size(), levels.size());
    for (std::size_t k = 0; k < levels.size(); ++k) {
        // The same triangles (as sorted corner triples), each once, in clusters covering the range.
        const auto triangles = [&](const std::vector<uint32_t>& idx) {
            std::vector<std::array<uint32_t, 3>> t;
            for (uint32_t i = levels[k].first_index; i < levels[k].first_index + levels[k].index_count; i += 3) {
                std::array<uint32_t, 3> tri{idx[i], idx[i + 1], idx[i + 2]};
                std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end()); // keeps the winding
                t.push_back(tri);
            }
            std::sort(t.begin(), t.end());
            return t;
        };
        EXPECT_EQ(triangles(mesh.indices), triangles(before)) << "level " << k;
        uint32_t next = levels[k].first_index;
        for (const TriangleCluster& c : clusters[k]) {
            EXPECT_EQ(c.first_index, next);
            next += c.index_count;
            EXPECT_LE(c.index_count, 3u * 124u);
        }
        EXPECT_EQ(next, levels[k].first_index + levels[k].index_count);
    }
    // A cluster that faces away from an eye holds only triangles facing away from it.
    const glm::vec3 eye(0.5f, 1.0f, 4.5f);
    std::size_t away = 0;
    for (const TriangleCluster& c : clusters[0]) {
        if (!faces_away(c, eye)) continue;
        ++away;
        for (uint32_t i = c.first_index; i < c.first_index + c.index_count; i += 3) {
            const glm::vec3 a(mesh.vertices[mesh.indices[i]].position_u), b(mesh.vertices[mesh.indices[i + 1]].position_u),
                d(mesh.vertices[mesh.indices[i + 2]].position_u);
            EXPECT_LE(glm::dot(glm::cross(b - a, d - a), eye - a), 1e-9f) << "cluster at index " << c.first_index;
        }
    }
    EXPECT_GT(away, clusters[0].size() / 5);
}

// The levels of detail are built in patches (each level the same patches' ranges, in order), each
// simplified with its border kept: level 0 holds the mesh's triangles, and any mix of levels, one per
// patch, is as closed as the mesh (no crack where a coarse patch meets a fine one).
TEST(LevelsOfDetail, PatchesMeetWithoutCracksAtAnyMixOfLevels) {
    const synth::Preset preset = synth::make_preset("knot");
    ASSERT_TRUE(is_closed_outward(preset.mesh));
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    IndexedVertices mesh = index_vertices(data.mesh, data.corner_uv);
    const auto sorted_triangles = [](std::span<const uint32_t> idx) {
        std::vector<std::array<uint32_t, 3>> t;
        for (std::size_t i = 0; i < idx.size(); i += 3) {
            std::array<uint32_t, 3> tri{idx[i], idx[i + 1], idx[i + 2]};
            std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end()); // keeps the winding
            t.push_back(tri);
        }
        std::sort(t.begin(), t.end());
        return t;
    };
    const auto before = sorted_triangles(mesh.indices);
    const LevelsOfDetail lod = build_levels_of_detail(mesh);
    ASSERT_GE(lod.levels.size(), 2u);
    ASSERT_GE(lod.patches.size(), preset.mesh.triangles.size() / kPatchTriangles);
    EXPECT_EQ(sorted_triangles(std::span(mesh.indices).first(lod.levels[0].index_count)), before);
    for (std::size_t k = 0; k < lod.levels.size(); ++k) {
        uint32_t next = lod.levels[k].first_index;
        double worst = 0.0;
        for (const MeshPatch& p : lod.patches) {
            ASSERT_EQ(p.levels.size(), lod.levels.size());
            EXPECT_EQ(p.levels[k].first_index, next) << "level " << k;
            next += p.levels[k].index_count;
            EXPECT_LE(p.levels[k].index_count, p.levels[0].index_count);
            EXPECT_LE(p.levels[0].index_count, 3 * kPatchTriangles);
            worst = std::max(worst, p.levels[k].error);
            if (k == 0) {
                // The sphere holds the patch's corners.
                for (uint32_t i = p.levels[0].first_index; i < p.levels[0].first_index + p.levels[0].index_count; ++i)
                    EXPECT_LE(glm::length(glm::vec3(mesh.vertices[mesh.indices[i]].position_u) - p.center), p.radius * 1.0001f);
            }
        }
        EXPECT_EQ(next, lod.levels[k].first_index + lod.levels[k].index_count) << "level " << k;
        EXPECT_EQ(lod.levels[k].error, worst) << "level " << k;
    }
    // Most patches simplify (a patch that could not keep its border keeps its triangles).
    EXPECT_LT(lod.levels[1].index_count, 6 * lod.levels[0].index_count / 10);

    std::mt19937 rng(7);
    Mesh mixed;
    for (const shared::RenderVertex& v : mesh.vertices) {
        mixed.positions.emplace_back(v.position_u);
        mixed.normals.emplace_back(v.normal_v);
    }
    for (int trial = 0; trial < 12; ++trial) {
        mixed.triangles.clear();
        std::uniform_int_distribution<std::size_t> pick(0, lod.levels.size() - 1);
        for (const MeshPatch& p : lod.patches) {
            const LevelOfDetail& r = p.levels[trial == 0 ? lod.levels.size() - 1 : pick(rng)];
            for (uint32_t i = r.first_index; i < r.first_index + r.index_count; i += 3)
                mixed.triangles.emplace_back(mesh.indices[i], mesh.indices[i + 1], mesh.indices[i + 2]);
        }
        EXPECT_TRUE(is_closed_outward(mixed)) << "mix " << trial;
    }
}

// With clusters (a closed mesh), each patch draws the coarsest level the view does not graze, and
// the patches at a silhouette keep every triangle. Against a ray-traced truth (synth's renderer, its
// shadows included), the frames are within 0.2 dB of the whole mesh's (issue 19's bound), where the
// one level drawn everywhere is not, from fewer triangles than the whole mesh, with its coverage.
TEST_F(RenderTest, PatchesAtASilhouetteKeepEveryTriangle) {
    // knot_hd's tube (64 sides) over half its length: triangles of about a pixel here, what levels of detail are for.
    synth::Preset preset = synth::make_preset("knot");
    preset.mesh = synth::make_torus_knot(2, 3, 1.0f, 0.3f, 800, 64, 8.0f);
    std::vector<Camera> cams;
    std::vector<PointLight> lights;
    for (const glm::dvec3& eye : {glm::dvec3(0.5, 1.0, 4.5), glm::dvec3(-3.0, -2.0, 2.5), glm::dvec3(3.5, 0.5, -1.5)}) {
        cams.push_back(make_camera(128, 128, 130.0, 130.0, 64.0, 64.0, eye, {0, 0, 0}));
        lights.push_back({eye + glm::dvec3(1.0, 2.0, 0.5), {30.0, 30.0, 30.0}});
    }
    const TruthAtlas atlas = atlas_from_truth(preset.mesh, preset.material, cams); // the knot's banded texture
    const Scene scene{.mesh = &preset.mesh, .corner_uv = atlas.atlas.corner_uv, .albedo = &atlas.image,
                      .material = {.specular = preset.material.lobe}};
    Renderer by_view(ctx(), scene, {.lod_max_error_px = 0.5, .cluster_culling = true});
    Renderer one_level(ctx(), scene, {.lod_max_error_px = 0.5});
    Renderer whole(ctx(), scene, {.cluster_culling = true});
    const std::size_t levels = by_view.levels_of_detail().size();
    ASSERT_GE(levels, 2u);
    ASSERT_EQ(one_level.levels_of_detail().size(), levels);
    const Settings s{.passes = Passes::Deferred};
    (void)by_view.accept_levels_of_detail(cams, lights, s, 0.0); // every level may be drawn
    (void)one_level.accept_levels_of_detail(cams, lights, s, 0.0);
    const synth::Renderer tracer(preset.mesh, preset.material);
    double worst_one_level = 0.0;
    std::size_t drawn = 0, drawn_whole = 0;
    for (std::size_t v = 0; v < cams.size(); ++v) {
        const synth::RenderedFrame truth = tracer.render(cams[v], lights[v]);
        const Frame f = by_view.render(cams[v], lights[v], s);
        const Frame o = one_level.render(cams[v], lights[v], s);
        const Frame w = whole.render(cams[v], lights[v], s);
        EXPECT_EQ(f.info.lod_level, levels - 1);
        EXPECT_GE(o.info.lod_level, 1u);
        std::size_t differ = 0;
        for (std::size_t i = 0; i < w.mask.size(); ++i) differ += (f.mask[i] != 0) != (w.mask[i] != 0) ? 1 : 0;
        const double by_view_db = display_psnr_where_either_covers(f, truth);
        const double one_level_db = display_psnr_where_either_covers(o, truth);
        const double whole_db = display_psnr_where_either_covers(w, truth);
        std::printf("view %zu: %zu triangles of %zu, %zu pixels covered by one only; against the truth: whole %.2f dB, "
                    "patches by the view %.2f dB, level %zu everywhere %.2f dB\n",
                    v, f.info.triangles, w.info.triangles, differ, whole_db, by_view_db, o.info.lod_level, one_level_db);
        EXPECT_EQ(differ, 0u) << v;
        // What the frame says it drew whole: some patches, not all; no patches without them.
        EXPECT_GE(f.info.patches, preset.mesh.triangles.size() / kPatchTriangles) << v;
        EXPECT_GT(f.info.patches_whole, 0u) << v;
        EXPECT_LT(f.info.patches_whole, f.info.patches) << v;
        EXPECT_EQ(o.info.patches, 0u) << v;
        EXPECT_EQ(w.info.patches, 0u) << v;
        EXPECT_LE(std::abs(by_view_db - whole_db), 0.2) << v;
        EXPECT_GT(whole_db, 30.0) << v;
        worst_one_level = std::max(worst_one_level, whole_db - one_level_db);
        drawn += f.info.triangles;
        drawn_whole += w.info.triangles;
    }
    EXPECT_GT(worst_one_level, 0.2); // the bound needs the patches by the view
    EXPECT_LT(drawn, 96 * drawn_whole / 100);

    // A constant albedo shows what the texture hides: where a silhouette runs between two triangles
    // of a patch, one facing the eye and one away, both seen at less than the grazing angle, the
    // patch keeps its triangles too (a coarse one moved an inner silhouette by a pixel here).
    const SceneData plain_data = constant_albedo(preset.mesh, glm::vec3(0.5f, 0.4f, 0.3f));
    const Scene plain = plain_data.scene(preset.material.lobe);
    Renderer plain_by_view(ctx(), plain, {.lod_max_error_px = 0.5, .cluster_culling = true});
    Renderer plain_whole(ctx(), plain, {.cluster_culling = true});
    (void)plain_by_view.accept_levels_of_detail(cams, lights, s, 0.0);
    for (std::size_t v = 0; v < cams.size(); ++v) {
        const double db =
            display_psnr_where_either_covers(plain_by_view.render(cams[v], lights[v], s), plain_whole.render(cams[v], lights[v], s));
        std::printf("view %zu, constant albedo: patches by the view %.2f dB against the whole mesh\n", v, db);
        EXPECT_GT(db, 45.0) << v;
    }

    // The patches depend on the light too (shadows): the same camera under another light draws what
    // a renderer that drew nothing before draws.
    Renderer fresh(ctx(), scene, {.lod_max_error_px = 0.5, .cluster_culling = true});
    (void)fresh.accept_levels_of_detail(cams, lights, s, 0.0);
    (void)by_view.render(cams[0], lights[0], s);
    expect_same_frame(by_view.render(cams[0], lights[1], s), fresh.render(cams[0], lights[1], s), "another light");
}

// may_graze is conservative: where a cluster's triangle is seen at more than `grazing` from its
// normal (or facing away under pi - grazing), at any of its corners, the cluster may graze; and it
// says no where the view is well within the cone's side.
TEST(LevelsOfDetail, MayGrazeHoldsEveryGrazedTriangle) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = constant_albedo(preset.mesh, glm::vec3(0.5f));
    IndexedVertices mesh = index_vertices(data.mesh, data.corner_uv);
    const LevelsOfDetail lod = build_levels_of_detail(mesh);
    const std::vector<std::vector<TriangleCluster>> clusters = cluster_levels(mesh, lod.levels, lod.patches);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::size_t grazed = 0, spared = 0;
    for (int e = 0; e < 40; ++e) {
        glm::vec3 eye(unit(rng), unit(rng), unit(rng));
        eye = glm::normalize(eye) * (e < 5 ? 0.8f : 3.0f + 2.0f * std::abs(unit(rng))); // a few inside the knot's hull
        const float grazing = glm::radians(e % 2 == 0 ? 80.0f : 88.0f);
        for (const std::vector<TriangleCluster>& level : clusters)
            for (std::size_t ci = 0; ci < level.size(); ci += 7) {
                const TriangleCluster& c = level[ci];
                bool any = false;
                for (uint32_t i = c.first_index; i < c.first_index + c.index_count && !any; i += 3) {
                    const glm::vec3 a(mesh.vertices[mesh.indices[i]].position_u), b(mesh.vertices[mesh.indices[i + 1]].position_u),
                        d(mesh.vertices[mesh.indices[i + 2]].position_u);
                    const glm::vec3 n = glm::cross(b - a, d - a);
                    if (!(glm::length(n) > 0.0f)) continue;
                    for (const glm::vec3& corner : {a, b, d, (a + b + d) / 3.0f}) {
                        const float cosine = glm::dot(glm::normalize(n), glm::normalize(eye - corner));
                        any = any || std::abs(cosine) < std::cos(grazing);
                    }
                }
                const bool may = may_graze(c, eye, grazing);
                if (any) {
                    EXPECT_TRUE(may) << "cluster " << ci << " eye " << e;
                }
                grazed += any ? 1 : 0;
                spared += may ? 0 : 1;
            }
    }
    EXPECT_GT(grazed, 100u);
    EXPECT_GT(spared, 1000u); // not every cluster: the test would then hold for any answer
}

// One frame drawn with two materials (the evaluation's bundle and core material) draws its light's
// shadow map once: a render() whose light and level of detail are the previous render()'s shades
// from the depth that frame left (FrameInfo::shadow_kept), with the same pixels, bit for bit, as a
// renderer drawing it afresh; another light draws it again, a frame without shadows leaves it,
// and a frame recorded into another target (the viewer) draws over it.
TEST_F(RenderTest, OneLightsShadowMapIsDrawnOnceForItsFrames) {
    const synth::Preset preset = synth::make_preset("knot");
    const SceneData data = knot_with_varied_atlas(preset);
    const Camera cam = make_camera(96, 80, 100.0, 100.0, 48.0, 40.0, {0.5, 1.0, 4.5}, {0, 0, 0});
    const Camera other_cam = make_camera(96, 80, 100.0, 100.0, 48.0, 40.0, {-2.0, 1.5, 3.5}, {0, 0, 0});
    const PointLight light{{2.0, 2.0, 3.0}, {20.0, 20.0, 20.0}};
    const PointLight other_light{{-2.5, 1.0, 2.5}, {15.0, 18.0, 20.0}};
    const CoreMaterial core{.roughness = 0.4, .f0 = 0.05, .f90 = 0.8};
    const Scene scene = data.scene(preset.material.lobe);
    const Settings deferred{.passes = Passes::Deferred};
    Renderer r(ctx(), scene);
    const auto fresh = [&](const Camera& c, const PointLight& l, bool core_material, const Settings& s) {
        Renderer f(ctx(), scene);
        if (core_material) f.set_material(core_material_gpu(core), true);
        const Frame frame = f.render(c, l, s);
        EXPECT_FALSE(frame.info.shadow_kept);
        return frame;
    };
    const Frame first = r.render(cam, light, deferred);
    EXPECT_TRUE(first.info.shadow_pass);
    EXPECT_FALSE(first.info.shadow_kept);
    r.set_material(core_material_gpu(core), true);
    const Frame core_frame = r.render(cam, light, deferred);
    EXPECT_TRUE(core_frame.info.shadow_pass);
    EXPECT_TRUE(core_frame.info.shadow_kept);
    EXPECT_TRUE(core_frame.info.gbuffer_kept);
    expect_same_frame(core_frame, fresh(cam, light, true, deferred), "the core material, the same light");
    EXPECT_NE(0, std::memcmp(core_frame.color.pixels.data(), first.color.pixels.data(), first.color.pixels.size() * sizeof(float)));
    r.set_specular(preset.material.lobe);
    const Frame moved = r.render(other_cam, light, {.passes = Passes::Fused}); // another camera and passes, the same light
    EXPECT_TRUE(moved.info.shadow_kept);
    expect_same_frame(moved, fresh(other_cam, light, false, {.passes = Passes::Fused}), "another camera");
    const Frame lit_other = r.render(cam, other_light, deferred);
    EXPECT_FALSE(lit_other.info.shadow_kept);
    expect_same_frame(lit_other, fresh(cam, other_light, false, deferred), "another light");
    const Frame unshadowed = r.render(cam, light, {.passes = Passes::Deferred, .shadows = false});
    EXPECT_FALSE(unshadowed.info.shadow_pass);
    EXPECT_FALSE(unshadowed.info.shadow_kept);
    const Frame back = r.render(cam, other_light, deferred); // the map still holds other_light's depth
    EXPECT_TRUE(back.info.shadow_kept);
    expect_same_frame(back, lit_other, "after a frame without shadows");
    // A frame recorded into another target draws the shadow map for its light: the next render() draws its own.
    gpu::RenderTarget target(ctx(), 96, 80, "second target");
    gpu::Sequence seq(ctx(), 4);
    seq.record([&](VkCommandBuffer cmd) { (void)r.record(cmd, target, cam, light, deferred); });
    seq.submit_and_wait();
    const Frame after_record = r.render(cam, other_light, deferred);
    EXPECT_FALSE(after_record.info.shadow_kept);
    expect_same_frame(after_record, lit_other, "after a recorded frame of another light");
}

} // namespace
} // namespace specula::render
