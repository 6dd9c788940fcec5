#include "geometry/ray_scene.h"

#include "core/error.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>

namespace specula {

namespace {

/// What Embree's error callback recorded. Lives on the heap so its address
/// stays valid when the RayScene is moved.
struct ErrorSink {
    std::mutex mutex;
    RTCError code = RTC_ERROR_NONE;
    std::string message;
};

// Embree's error callback: record, never throw (style.md habit 6).
void record_embree_error(void* user, RTCError code, const char* str) noexcept {
    auto* sink = static_cast<ErrorSink*>(user);
    try {
        const std::lock_guard lock(sink->mutex);
        if (sink->code == RTC_ERROR_NONE) {
            sink->code = code;
            sink->message = str != nullptr ? str : "";
        }
    } catch (...) {
        // Out of memory while recording: rtcGetDeviceError still reports the code.
    }
}

const char* error_name(RTCError code) {
    switch (code) {
    case RTC_ERROR_NONE: return "RTC_ERROR_NONE";
    case RTC_ERROR_UNKNOWN: return "RTC_ERROR_UNKNOWN";
    case RTC_ERROR_INVALID_ARGUMENT: return "RTC_ERROR_INVALID_ARGUMENT";
    case RTC_ERROR_INVALID_OPERATION: return "RTC_ERROR_INVALID_OPERATION";
    case RTC_ERROR_OUT_OF_MEMORY: return "RTC_ERROR_OUT_OF_MEMORY";
    case RTC_ERROR_UNSUPPORTED_CPU: return "RTC_ERROR_UNSUPPORTED_CPU";
    case RTC_ERROR_CANCELLED: return "RTC_ERROR_CANCELLED";
    }
    return "RTC_ERROR_?";
}

void init_ray(RTCRay& r, const glm::vec3& origin, const glm::vec3& dir, float tmin, float tmax) {
    r.org_x = origin.x;
    r.org_y = origin.y;
    r.org_z = origin.z;
    r.tnear = tmin;
    r.dir_x = dir.x;
    r.dir_y = dir.y;
    r.dir_z = dir.z;
    r.time = 0.0f;
    r.tfar = tmax;
    r.mask = 0xFFFFFFFFu;
    r.id = 0;
    r.flags = 0;
}

void init_ray_hit(RTCRayHit& rh, const glm::vec3& origin, const glm::vec3& dir, float tmin, float tmax) {
    init_ray(rh.ray, origin, dir, tmin, tmax);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.u = 0.0f;
    rh.hit.v = 0.0f;
}

std::optional<RayHit> to_hit(const RTCRayHit& rh) {
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
    return RayHit{rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v};
}

// Embree's occluded calls set tfar to -inf on a hit.
bool was_occluded(const RTCRay& r) { return r.tfar < 0.0f && std::isinf(r.tfar); }

} // namespace

struct RayScene::Impl {
    std::unique_ptr<ErrorSink> errors = std::make_unique<ErrorSink>();
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;

    Impl() = default;
    Impl(const Impl&) = delete;
    Impl& operator=(const Impl&) = delete;
    ~Impl() {
        if (scene != nullptr) rtcReleaseScene(scene);
        if (device != nullptr) rtcReleaseDevice(device);
    }

    /// Throws when Embree reported an error since the last check.
    void check(const char* what) const {
        const RTCError code = device != nullptr ? rtcGetDeviceError(device) : rtcGetDeviceError(nullptr);
        std::string message;
        RTCError recorded = RTC_ERROR_NONE;
        {
            const std::lock_guard lock(errors->mutex);
            recorded = errors->code;
            message = errors->message;
            errors->code = RTC_ERROR_NONE;
            errors->message.clear();
        }
        const RTCError first = recorded != RTC_ERROR_NONE ? recorded : code;
        if (first != RTC_ERROR_NONE)
            throw Error(std::string("Embree: ") + what + ": " + error_name(first) + (message.empty() ? "" : ": " + message));
    }
};

RayScene::RayScene(const Mesh& mesh, const RaySceneOptions& options) : m_impl(std::make_unique<Impl>()) {
    if (mesh.triangles.empty() || mesh.positions.empty()) throw Error("RayScene: the mesh has no triangles");
    for (const glm::uvec3& tri : mesh.triangles)
        if (tri.x >= mesh.positions.size() || tri.y >= mesh.positions.size() || tri.z >= mesh.positions.size())
            throw Error("RayScene: a triangle index is out of range");
    // Embree drops triangles with vertices it cannot trace (non-finite or beyond FLT_LARGE)
    // without a word: refuse them instead, so a hole never passes for a result.
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
        const glm::vec3& p = mesh.positions[i];
        if (!(std::abs(p.x) <= kMaxRayCoordinate && std::abs(p.y) <= kMaxRayCoordinate && std::abs(p.z) <= kMaxRayCoordinate))
            throw Error("RayScene: vertex " + std::to_string(i) + " (" + std::to_string(p.x) + ", " + std::to_string(p.y) +
                        ", " + std::to_string(p.z) + ") is not finite or beyond +-1e18, which the ray tracer cannot trace");
    }

    const std::string config = "verbose=0" + (options.build_threads > 0 ? ",threads=" + std::to_string(options.build_threads) : std::string());
    m_impl->device = rtcNewDevice(config.c_str());
    if (m_impl->device == nullptr) {
        // The device-less error query reports why rtcNewDevice failed.
        throw Error(std::string("Embree: rtcNewDevice failed: ") + error_name(rtcGetDeviceError(nullptr)));
    }
    rtcSetDeviceErrorFunction(m_impl->device, record_embree_error, m_impl->errors.get());

    m_impl->scene = rtcNewScene(m_impl->device);
    m_impl->check("rtcNewScene");
    rtcSetSceneFlags(m_impl->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(m_impl->scene, RTC_BUILD_QUALITY_HIGH);

    RTCGeometry geom = rtcNewGeometry(m_impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    m_impl->check("rtcNewGeometry");
    // Embree-owned copies (rtcSetNewGeometryBuffer pads them as Embree needs),
    // so the scene does not depend on the Mesh's lifetime.
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                 3 * sizeof(float), mesh.positions.size()));
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                   3 * sizeof(unsigned), mesh.triangles.size()));
    if (vertices == nullptr || indices == nullptr) {
        rtcReleaseGeometry(geom);
        m_impl->check("rtcSetNewGeometryBuffer");
        throw Error("Embree: rtcSetNewGeometryBuffer returned no buffer");
    }
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
        vertices[3 * i + 0] = mesh.positions[i].x;
        vertices[3 * i + 1] = mesh.positions[i].y;
        vertices[3 * i + 2] = mesh.positions[i].z;
    }
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        indices[3 * i + 0] = mesh.triangles[i].x;
        indices[3 * i + 1] = mesh.triangles[i].y;
        indices[3 * i + 2] = mesh.triangles[i].z;
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(m_impl->scene, geom, 0); // geomID 0: primID is the mesh's triangle index
    rtcReleaseGeometry(geom);
    rtcCommitScene(m_impl->scene);
    m_impl->check("building the triangle scene");

    m_bounds = mesh_bounds(mesh);
    m_ray_offset = kRayOffsetRelative * glm::length(m_bounds.max - m_bounds.min);
    if (!(m_ray_offset > 0.0f)) m_ray_offset = kRayOffsetRelative; // a single point-like mesh: any small offset
    m_triangle_count = mesh.triangles.size();
}

RayScene::~RayScene() = default;
RayScene::RayScene(RayScene&&) noexcept = default;
RayScene& RayScene::operator=(RayScene&&) noexcept = default;

void RayScene::check_ray(const Ray& ray, const char* what, std::size_t index) {
    auto coordinate_ok = [](const glm::vec3& v) {
        return std::abs(v.x) <= kMaxRayCoordinate && std::abs(v.y) <= kMaxRayCoordinate && std::abs(v.z) <= kMaxRayCoordinate;
    };
    // Comparisons are false for NaN, so each test below also refuses NaN.
    const bool ok = coordinate_ok(ray.origin) && coordinate_ok(ray.dir) &&
                    ray.tmin >= 0.0f && std::isfinite(ray.tmin) && !std::isnan(ray.tmax);
    if (ok) return;
    char text[512];
    std::snprintf(text, sizeof text,
                  "RayScene::%s: ray %zu is outside what the ray tracer accepts: origin (%g, %g, %g), direction "
                  "(%g, %g, %g), segment [%g, %g] (coordinates must be finite with magnitude at most %g, "
                  "0 <= tmin finite, tmax not NaN); the camera, light or surface point it was cast "
                  "from is out of range",
                  what, index, double(ray.origin.x), double(ray.origin.y), double(ray.origin.z), double(ray.dir.x),
                  double(ray.dir.y), double(ray.dir.z), double(ray.tmin), double(ray.tmax), double(kMaxRayCoordinate));
    throw Error(text);
}

std::optional<RayHit> RayScene::intersect(const glm::vec3& origin, const glm::vec3& dir, float tmin, float tmax) const {
    check_ray(Ray{origin, tmin, dir, tmax}, "intersect");
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    init_ray_hit(rh, origin, dir, tmin, tmax);
    rtcIntersect1(m_impl->scene, &context, &rh);
    return to_hit(rh);
}

bool RayScene::occluded(const glm::vec3& origin, const glm::vec3& dir, float tmin, float tmax) const {
    check_ray(Ray{origin, tmin, dir, tmax}, "occluded");
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay r;
    init_ray(r, origin, dir, tmin, tmax);
    rtcOccluded1(m_impl->scene, &context, &r);
    return was_occluded(r);
}

// The batched calls loop over rtcIntersect1 / rtcOccluded1 rather than the
// stream API (rtcIntersect1M / rtcOccluded1M): with Embree 3.13.5 as Debian
// builds it, the stream path missed a hit that the single-ray path finds (the
// second ray of a 3-ray batch, nearly axis-aligned, through a box; see
// tests/geometry/ray_scene_test.cpp, BatchesAgreeWithSingleRaysOnNearlyAxisAlignedRays),
// and for incoherent rays single-ray traversal is as fast.
void RayScene::intersect(std::span<const Ray> rays, std::span<std::optional<RayHit>> out) const {
    if (out.size() != rays.size()) throw Error("RayScene::intersect: output size differs from the ray count");
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (std::size_t i = 0; i < rays.size(); ++i) check_ray(rays[i], "intersect", i);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        RTCRayHit rh;
        init_ray_hit(rh, rays[i].origin, rays[i].dir, rays[i].tmin, rays[i].tmax);
        rtcIntersect1(m_impl->scene, &context, &rh);
        out[i] = to_hit(rh);
    }
}

void RayScene::occluded(std::span<const Ray> rays, std::span<std::uint8_t> out) const {
    if (out.size() != rays.size()) throw Error("RayScene::occluded: output size differs from the ray count");
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (std::size_t i = 0; i < rays.size(); ++i) check_ray(rays[i], "occluded", i);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        RTCRay r;
        init_ray(r, rays[i].origin, rays[i].dir, rays[i].tmin, rays[i].tmax);
        rtcOccluded1(m_impl->scene, &context, &r);
        out[i] = was_occluded(r) ? 1 : 0;
    }
}

Ray RayScene::ray_toward(const glm::vec3& p, const glm::vec3& n, const glm::vec3& target) const {
    Ray r;
    r.origin = p + m_ray_offset * n;
    const glm::vec3 to = target - r.origin;
    const float dist = glm::length(to);
    r.dir = dist > 0.0f ? to / dist : n;
    r.tmin = 0.0f;
    r.tmax = std::max(0.0f, dist - m_ray_offset);
    return r;
}

} // namespace specula
