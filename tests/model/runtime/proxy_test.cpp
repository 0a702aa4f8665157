// God-object proxy (proxy.hpp) on small hand-built meshes with known answers: contact and
// release on a plane, continuity across a shared edge of coplanar triangles and over mildly
// convex and concave creases, three planes at a concave corner, the deep-penetration
// direction in a closed cube (and a tool that tunnels through it in one cycle), a ball tool,
// the per-update travel cap, a surface moving under a pressed tool, damping, refusals and no
// heap in the RT call.
#include "trainer/model/proxy.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model {
namespace {

constexpr float kStiffness = 1000.0F;  // N/m: 1 mm of penetration = 1 N

struct Scene {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
  core::Arena arena;
  BucketGrid grid;
  GodObjectProxy proxy;

  const ProxyContact& step(const Vec3& tool, const Vec3& velocity = Vec3::Zero()) {
    EXPECT_TRUE(grid.rebuild(positions, triangles).is_ok());
    const core::Status status = proxy.update(tool, velocity, {positions, triangles}, grid);
    EXPECT_TRUE(status.is_ok()) << status.detail();
    return proxy.contact();
  }
};

Scene make_scene(std::vector<float> positions, std::vector<std::uint32_t> triangles,
                 ProxySettings settings = {}) {
  if (settings.stiffness_n_per_m == 0.0F) settings.stiffness_n_per_m = kStiffness;
  auto arena = core::Arena::create(8U << 20);
  EXPECT_TRUE(arena.has_value());
  core::Arena owned = std::move(arena).value();
  auto grid = BucketGrid::create({1024, 1024, 0.002F, 1024, 1U << 16}, owned);
  EXPECT_TRUE(grid.has_value());
  auto proxy = GodObjectProxy::create(settings, owned);
  EXPECT_TRUE(proxy.has_value()) << (proxy ? "" : proxy.error().message);
  return Scene{std::move(positions), std::move(triangles), std::move(owned),
               std::move(grid).value(), std::move(proxy).value()};
}

// Square [−h, h]² at z = 0, normal +z, split along the diagonal b–d (x + y = 0).
Scene flat_square(ProxySettings settings = {}, float h = 0.01F) {
  return make_scene({-h, -h, 0, h, -h, 0, h, h, 0, -h, h, 0}, {0, 1, 3, 1, 2, 3}, settings);
}

// Two strips meeting at x = 0 with slope ±tan θ: `ridge` = roof (convex, surface
// z = −|x| tan θ), otherwise valley (concave, z = |x| tan θ). Outward normals up.
Scene crease(float angle_rad, bool ridge, const ProxySettings& settings) {
  const float length = 0.01F;
  const float width = 0.01F;
  const float drop = (ridge ? -1.0F : 1.0F) * length * std::tan(angle_rad);
  return make_scene({-length, -width, drop, 0, -width, 0, 0, width, 0, -length, width, drop,
                     length, -width, drop, length, width, drop},
                    {0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2}, settings);
}

float crease_height(float x, float angle_rad, bool ridge) {
  return (ridge ? -1.0F : 1.0F) * std::abs(x) * std::tan(angle_rad);
}

// Cube [−h, h]³, outward normals.
Scene cube(float h = 0.01F) {
  std::vector<float> positions;
  for (int v = 0; v < 8; ++v) {
    positions.insert(positions.end(), {(v & 1) ? h : -h, (v & 2) ? h : -h, (v & 4) ? h : -h});
  }
  return make_scene(positions, {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5});
}

// Drags the tool along `path` (already in contact at path[0]) and checks the force stays
// continuous: each step changes it by at most k (|Δtool| + |Δproxy|), |Δproxy| at most
// |Δtool| where the proxy is a projection and at most the travel cap where it must jump
// (convex creases), plus float noise.
void expect_continuous_drag(Scene& scene, const std::vector<Vec3>& path, float proxy_bound_m) {
  Vec3 previous_force = scene.step(path.front()).force_n;
  Vec3 previous_proxy = scene.proxy.contact().proxy_m;
  ASSERT_TRUE(scene.proxy.contact().in_contact);
  for (std::size_t i = 1; i < path.size(); ++i) {
    const ProxyContact& contact = scene.step(path[i]);
    ASSERT_TRUE(contact.in_contact) << "step " << i;
    const float tool_step = (path[i] - path[i - 1]).norm();
    ASSERT_LE((contact.proxy_m - previous_proxy).norm(), std::max(tool_step, proxy_bound_m) + 1e-7F)
        << "step " << i;
    const float bound = kStiffness * (tool_step + std::max(tool_step, proxy_bound_m)) + 1e-4F;
    ASSERT_LE((contact.force_n - previous_force).norm(), bound) << "step " << i;
    previous_force = contact.force_n;
    previous_proxy = contact.proxy_m;
  }
}

TEST(GodObjectProxy, ContactOnAPlaneAndCleanRelease) {
  Scene scene = flat_square();
  const Vec3 start(0.002F, 0.003F, 0.005F);
  EXPECT_FALSE(scene.step(start).in_contact);
  for (int i = 1; i <= 70; ++i) {
    const Vec3 tool = start - Vec3(0, 0, 1e-4F * static_cast<float>(i));
    const ProxyContact& contact = scene.step(tool);
    if (tool.z() >= 0.0F) {
      ASSERT_FALSE(contact.in_contact) << tool.z();
      EXPECT_EQ(contact.force_n, Vec3::Zero());
      EXPECT_EQ(contact.proxy_m, tool);
    } else {
      ASSERT_TRUE(contact.in_contact) << tool.z();
      EXPECT_LT((contact.proxy_m - Vec3(0.002F, 0.003F, 0)).norm(), 1e-6F);
      EXPECT_LT((contact.force_n - Vec3(0, 0, -kStiffness * tool.z())).norm(), 1e-3F);
      EXPECT_LT((contact.normal - Vec3::UnitZ()).norm(), 1e-6F);
      EXPECT_NEAR(contact.depth_m, -tool.z(), 1e-6F);
    }
  }
  // Lift: free again, the proxy is the tool, no force at all.
  const ProxyContact& lifted = scene.step(Vec3(0.002F, 0.003F, 1e-4F));
  EXPECT_FALSE(lifted.in_contact);
  EXPECT_EQ(lifted.force_n, Vec3::Zero());
  // And it starts again as new.
  EXPECT_TRUE(scene.step(Vec3(0.0025F, 0.003F, -1e-4F)).in_contact);
  scene.proxy.reset(Vec3(0, 0, 0.01F));
  EXPECT_FALSE(scene.proxy.contact().in_contact);
  EXPECT_FALSE(scene.step(Vec3(0, 0, 0.009F)).in_contact);
}

TEST(GodObjectProxy, SlidesAcrossASharedEdgeOfCoplanarTriangles) {
  Scene scene = flat_square();
  scene.step({-0.008F, 0.002F, 0.001F});
  std::vector<Vec3> path;
  for (int i = 0; i <= 1600; ++i) path.emplace_back(-0.008F + 1e-5F * static_cast<float>(i), 0.002F, -0.001F);
  bool saw_first = false;
  bool saw_second = false;
  Vec3 previous_force = scene.step(path.front()).force_n;
  for (int i = 0; i < 10; ++i) previous_force = scene.step(path.front()).force_n;
  for (std::size_t i = 1; i < path.size(); ++i) {
    const ProxyContact& contact = scene.step(path[i]);
    ASSERT_TRUE(contact.in_contact);
    EXPECT_LT((contact.force_n - Vec3(0, 0, 1.0F)).norm(), 1e-3F) << "step " << i;
    ASSERT_LE((contact.force_n - previous_force).norm(), 2.0F * kStiffness * 1e-5F + 1e-4F);
    previous_force = contact.force_n;
    saw_first |= contact.triangle == 0;
    saw_second |= contact.triangle == 1;
  }
  EXPECT_TRUE(saw_first && saw_second);
}

void drag_over_crease(bool ridge) {
  const float angle = 15.0F * std::numbers::pi_v<float> / 180.0F;
  ProxySettings settings;
  settings.max_travel_per_update_m = 2e-5F;  // twice the tool's 1e-5 m per update
  Scene scene = crease(angle, ridge, settings);
  const float depth = 0.001F;
  scene.step({-0.006F, 0.001F, crease_height(-0.006F, angle, ridge) + 0.002F});
  std::vector<Vec3> path;
  for (int i = 0; i <= 1200; ++i) {
    const float x = -0.006F + 1e-5F * static_cast<float>(i);
    path.emplace_back(x, 0.001F, crease_height(x, angle, ridge) - depth);
  }
  const Vec3 first_normal(ridge ? -std::sin(angle) : std::sin(angle), 0, std::cos(angle));
  const Vec3 second_normal(-first_normal.x(), 0, first_normal.z());
  for (int i = 0; i < 50; ++i) scene.step(path.front());  // settle on the first side
  const ProxyContact start = scene.proxy.contact();
  ASSERT_TRUE(start.in_contact);
  EXPECT_LT((start.force_n.normalized() - first_normal).norm(), 1e-3F);
  EXPECT_NEAR(start.force_n.norm(), kStiffness * depth * std::cos(angle), 1e-3F);
  expect_continuous_drag(scene, path, settings.max_travel_per_update_m);
  const ProxyContact end = scene.proxy.contact();
  EXPECT_LT((end.force_n.normalized() - second_normal).norm(), 1e-3F);
  EXPECT_NEAR(end.force_n.norm(), kStiffness * depth * std::cos(angle), 1e-3F);
}

TEST(GodObjectProxy, SlidesContinuouslyOverAConvexCrease) { drag_over_crease(true); }
TEST(GodObjectProxy, SlidesContinuouslyThroughAConcaveCrease) { drag_over_crease(false); }

TEST(GodObjectProxy, ThreePlanesHoldItInAConcaveCorner) {
  const float l = 0.01F;
  // Floor z = 0 (+z), wall x = 0 (+x), wall y = 0 (+y): the free space is the octant x, y, z > 0.
  Scene scene = make_scene({0, 0, 0, l, 0, 0, l, l, 0, 0, l, 0,     // floor
                            0, 0, 0, 0, l, 0, 0, l, l, 0, 0, l,     // wall x = 0
                            0, 0, 0, 0, 0, l, l, 0, l, l, 0, 0},    // wall y = 0
                           {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7, 8, 9, 10, 8, 10, 11});
  const Vec3 start(0.005F, 0.005F, 0.005F);
  const Vec3 end(-0.001F, -0.002F, -0.003F);
  EXPECT_FALSE(scene.step(start).in_contact);
  for (int i = 1; i <= 100; ++i) scene.step(start + (end - start) * (static_cast<float>(i) / 100.0F));
  const ProxyContact corner = scene.step(end);
  ASSERT_TRUE(corner.in_contact);
  EXPECT_LT(corner.proxy_m.norm(), 1e-6F);
  EXPECT_LT((corner.force_n - kStiffness * Vec3(0.001F, 0.002F, 0.003F)).norm(), 1e-3F);
  EXPECT_GE(corner.feature, TriangleFeature::vertex0);
  // Back out along one wall's normal only: two planes (the floor–wall edge) hold it.
  for (int i = 0; i < 5; ++i) scene.step({0.002F, -0.001F, -0.002F});  // 2 mm at ≤ 0.5 mm
  const ProxyContact edge = scene.step({0.002F, -0.001F, -0.002F});
  ASSERT_TRUE(edge.in_contact);
  EXPECT_LT((edge.proxy_m - Vec3(0.002F, 0, 0)).norm(), 1e-6F);
}

TEST(GodObjectProxy, DeepPenetrationNeverSnapsThroughACube) {
  Scene scene = cube();
  const Vec3 above(0.001F, 0.002F, 0.012F);
  EXPECT_FALSE(scene.step(above).in_contact);
  // Down through the top, past the centre (where the nearest face is a side face) and out
  // through the bottom: the force keeps pointing up, growing with the depth.
  for (int i = 1; i <= 200; ++i) {
    const Vec3 tool = above - Vec3(0, 0, 2e-4F * static_cast<float>(i));
    const ProxyContact& contact = scene.step(tool);
    if (tool.z() >= 0.01F) continue;
    ASSERT_TRUE(contact.in_contact) << tool.z();
    EXPECT_LT((contact.force_n.normalized() - Vec3::UnitZ()).norm(), 1e-5F) << tool.z();
    EXPECT_NEAR(contact.force_n.norm(), kStiffness * (0.01F - tool.z()), 1e-3F);
  }
}

TEST(GodObjectProxy, ATunnellingToolIsCaughtOnTheNearSide) {
  Scene scene = cube();
  EXPECT_FALSE(scene.step({0.003F, 0.0F, 0.02F}).in_contact);
  // One cycle from above the cube to below it.
  const ProxyContact& contact = scene.step({0.003F, 0.0F, -0.02F});
  ASSERT_TRUE(contact.in_contact);
  EXPECT_LT((contact.proxy_m - Vec3(0.003F, 0, 0.01F)).norm(), 1e-6F);
  EXPECT_LT((contact.force_n.normalized() - Vec3::UnitZ()).norm(), 1e-5F);
}

TEST(GodObjectProxy, BallToolTouchesAtItsRadius) {
  ProxySettings settings;
  settings.tool_radius_m = 0.002F;
  Scene scene = flat_square(settings);
  EXPECT_FALSE(scene.step({0.001F, 0.001F, 0.005F}).in_contact);
  EXPECT_FALSE(scene.step({0.001F, 0.001F, 0.0021F}).in_contact);
  const ProxyContact& touching = scene.step({0.001F, 0.001F, 0.0015F});
  ASSERT_TRUE(touching.in_contact);
  EXPECT_LT((touching.proxy_m - Vec3(0.001F, 0.001F, 0.002F)).norm(), 1e-6F);
  EXPECT_LT((touching.force_n - Vec3(0, 0, 0.5F)).norm(), 1e-3F);
  const ProxyContact& through = scene.step({0.001F, 0.001F, -0.001F});
  ASSERT_TRUE(through.in_contact);
  EXPECT_LT((through.force_n - Vec3(0, 0, 3.0F)).norm(), 1e-3F);
  EXPECT_FALSE(scene.step({0.001F, 0.001F, 0.0025F}).in_contact);
}

TEST(GodObjectProxy, TravelPerUpdateIsCapped) {
  ProxySettings settings;
  settings.max_travel_per_update_m = 0.001F;
  Scene scene = flat_square(settings);
  scene.step({-0.004F, 0, 0.001F});
  ASSERT_TRUE(scene.step({-0.004F, 0, -0.001F}).in_contact);
  Vec3 previous = scene.proxy.contact().proxy_m;
  const Vec3 tool(0.004F, 0.0F, -0.001F);  // 8 mm sideways in one cycle
  for (int i = 0; i < 12; ++i) {  // 9.2 mm of walk (via the diagonal) at 1 mm per update
    const ProxyContact& contact = scene.step(tool);
    ASSERT_TRUE(contact.in_contact);
    EXPECT_LE((contact.proxy_m - previous).norm(), 0.001F + 1e-6F);
    previous = contact.proxy_m;
  }
  EXPECT_LT((previous - Vec3(0.004F, 0, 0)).norm(), 1e-5F);
}

TEST(GodObjectProxy, FollowsADeformingSurface) {
  Scene scene = flat_square();
  scene.step({0.001F, 0.001F, 0.001F});
  ASSERT_TRUE(scene.step({0.001F, 0.001F, -0.001F}).in_contact);
  for (std::size_t v = 0; v < 4; ++v) scene.positions[3 * v + 2] = 0.0005F;  // the wall comes up
  const ProxyContact& contact = scene.step({0.001F, 0.001F, -0.001F});
  ASSERT_TRUE(contact.in_contact);
  EXPECT_NEAR(contact.surface_point_m.z(), 0.0005F, 1e-7F);
  EXPECT_LT((contact.force_n - Vec3(0, 0, 1.5F)).norm(), 1e-3F);
}

TEST(GodObjectProxy, DampingActsAlongTheNormalAndNeverPulls) {
  ProxySettings settings;
  settings.damping_n_s_per_m = 2.0F;
  Scene scene = flat_square(settings);
  scene.step({0, 0.001F, 0.001F});
  const ProxyContact& pressing = scene.step({0, 0.001F, -0.001F}, {0.1F, 0, -0.1F});
  EXPECT_LT((pressing.force_n - Vec3(0, 0, 1.2F)).norm(), 1e-3F);  // tangential velocity ignored
  const ProxyContact& withdrawing = scene.step({0, 0.001F, -0.001F}, {0, 0, 1.0F});
  ASSERT_TRUE(withdrawing.in_contact);
  EXPECT_LT(withdrawing.force_n.norm(), 1e-6F);  // 1 N − 2 N clipped to zero, not −1 N
}

TEST(GodObjectProxy, RefusesBadSettingsAndNonFiniteInput) {
  auto arena = core::Arena::create(1U << 20);
  ASSERT_TRUE(arena.has_value());
  ProxySettings bad;
  bad.stiffness_n_per_m = 0.0F;
  auto created = GodObjectProxy::create(bad, arena.value());
  ASSERT_FALSE(created.has_value());
  EXPECT_NE(created.error().message.find("stiffness"), std::string::npos);
  bad.stiffness_n_per_m = 100.0F;
  bad.tool_radius_m = -1.0F;
  EXPECT_FALSE(GodObjectProxy::create(bad, arena.value()).has_value());

  Scene scene = flat_square();
  scene.step({0, 0.001F, 0.001F});
  ASSERT_TRUE(scene.step({0, 0.001F, -0.001F}).in_contact);
  const Vec3 before = scene.proxy.contact().force_n;
  EXPECT_EQ(scene.proxy.update({NAN, 0, 0}, Vec3::Zero(), {scene.positions, scene.triangles}, scene.grid).code(),
            core::StatusCode::numeric_error);
  EXPECT_EQ(scene.proxy.contact().force_n, before);
}

TEST(GodObjectProxy, OverflowingCandidatesKeepsTheContact) {
  ProxySettings settings;
  settings.max_candidates = 2;  // the two triangles of the square, not a third
  Scene scene = make_scene({-0.01F, -0.01F, 0, 0.01F, -0.01F, 0, 0.01F, 0.01F, 0, -0.01F, 0.01F, 0,
                            0.005F, -0.001F, -0.004F, 0.006F, 0.001F, -0.004F, 0.005F, 0.001F, 0.0005F},
                           {0, 1, 3, 1, 2, 3, 4, 5, 6}, settings);
  scene.step({-0.005F, 0, 0.001F});
  ASSERT_TRUE(scene.step({-0.005F, 0, -0.001F}).in_contact);
  // Drag towards the spike: where a query sees three triangles it overflows; the proxy must
  // then keep its contact (and push), never fall free.
  int overflows = 0;
  // (The grid returns only triangles whose box overlaps the query: the spike's box begins at
  // x = 5 mm, so the drag goes that far.)
  for (int i = 1; i <= 1000; ++i) {
    const Vec3 tool(-0.005F + 1e-5F * static_cast<float>(i), 0, -0.001F);
    ASSERT_TRUE(scene.grid.rebuild(scene.positions, scene.triangles).is_ok());
    const core::Status status =
        scene.proxy.update(tool, Vec3::Zero(), {scene.positions, scene.triangles}, scene.grid);
    if (!status.is_ok()) {
      ASSERT_EQ(status.code(), core::StatusCode::capacity_exceeded);
      ++overflows;
    }
    ASSERT_TRUE(scene.proxy.contact().in_contact) << i;
    ASSERT_GT(scene.proxy.contact().force_n.z(), 0.9F) << i;
  }
  EXPECT_GT(overflows, 0);
}

TEST(GodObjectProxy, NoHeapInUpdate) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  Scene scene = cube();
  scene.arena.seal();
  scene.step({0.001F, 0.002F, 0.012F});
  float checksum = 0.0F;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int i = 0; i < 5000; ++i) {
    const float phase = 0.002F * static_cast<float>(i);
    const Vec3 tool(0.008F * std::sin(phase), 0.002F, 0.01F - 0.003F * std::sin(3.0F * phase));
    if (!scene.grid.rebuild(scene.positions, scene.triangles).is_ok()) break;
    if (!scene.proxy.update(tool, Vec3::Zero(), {scene.positions, scene.triangles}, scene.grid).is_ok()) break;
    checksum += scene.proxy.contact().force_n.z();
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(checksum, 0.0F);
}

}  // namespace
}  // namespace trainer::model
