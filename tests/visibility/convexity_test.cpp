// Convexity (engine/visibility/convexity.h): when the mesh cannot occlude itself.
#include "visibility/convexity.h"

#include "test_meshes.h"

#include <gtest/gtest.h>

namespace specula {
namespace {

TEST(Convexity, SphereIsConvex) {
    const ConvexityReport r = analyze_convexity(test::sphere(1.0f, 16, 24));
    EXPECT_TRUE(r.convex) << r.reason;
    EXPECT_TRUE(r.closed);
    EXPECT_TRUE(r.connected);
    EXPECT_EQ(r.reflex_edges, 0u);
    EXPECT_TRUE(r.reason.empty());
}

TEST(Convexity, CubeWithSplitVerticesIsConvex) {
    // 24 vertices (face normals): welding by position closes it; coplanar pairs pass the tolerance.
    const ConvexityReport r = analyze_convexity(test::box({-1, -2, -3}, {4, 5, 6}));
    EXPECT_TRUE(r.convex) << r.reason;
    EXPECT_EQ(r.welded_vertices, 8u);
    EXPECT_EQ(r.edges, 18u);
}

TEST(Convexity, LShapeIsNotConvex) {
    const ConvexityReport r = analyze_convexity(test::l_shape());
    EXPECT_TRUE(r.closed);
    EXPECT_TRUE(r.connected);
    EXPECT_FALSE(r.convex);
    EXPECT_EQ(r.reflex_edges, 1u); // the inner vertical corner
    EXPECT_NE(r.reason.find("reflex"), std::string::npos);
}

TEST(Convexity, TorusIsNotConvex) {
    const ConvexityReport r = analyze_convexity(test::torus(1.0f, 0.3f, 24, 12));
    EXPECT_TRUE(r.closed);
    EXPECT_FALSE(r.convex);
    EXPECT_GT(r.reflex_edges, 0u);
}

TEST(Convexity, OpenMeshIsNotConvex) {
    const ConvexityReport plane = analyze_convexity(test::plane(1.0f, 4));
    EXPECT_FALSE(plane.convex);
    EXPECT_FALSE(plane.closed);
    EXPECT_EQ(plane.boundary_edges, 16u);
    const ConvexityReport with_box = analyze_convexity(test::plane_with_box());
    EXPECT_FALSE(with_box.convex);
    EXPECT_NE(with_box.reason.find("open"), std::string::npos);
    // A sphere with one triangle removed.
    Mesh holed = test::sphere(1.0f, 8, 8);
    holed.triangles.pop_back();
    EXPECT_FALSE(analyze_convexity(holed).convex);
}

TEST(Convexity, SeparatePiecesAreNotConvex) {
    const ConvexityReport r = analyze_convexity(test::merge(test::sphere(1.0f, 8, 8), test::box({3, 3, 3}, {4, 4, 4})));
    EXPECT_TRUE(r.closed);
    EXPECT_FALSE(r.connected);
    EXPECT_EQ(r.components, 2u);
    EXPECT_FALSE(r.convex);
}

TEST(Convexity, InsideOutSphereIsNotConvex) {
    Mesh m = test::sphere(1.0f, 8, 8);
    for (glm::uvec3& t : m.triangles) std::swap(t.y, t.z);
    EXPECT_FALSE(analyze_convexity(m).convex);
}

} // namespace
} // namespace specula
