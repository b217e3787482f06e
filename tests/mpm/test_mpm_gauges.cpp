// Gauges ([[gauge]], docs/mpm_results.md): depth, depth-averaged velocity and density of the
// flow across a line, against a layer of known depth, speed and density, level and on a slope.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <granflow/mpm/driver.hpp>

#include "tiny_column.hpp"

using namespace granflow;
using namespace granflow::mpm;

namespace {

// A layer 6 cm deep on a 1 cm grid (points 5 mm apart), seeded level; the frame rotates it by
// `angle` about the origin (a layer on a slope falling to the right) and moves it at `speed`
// along its base.
struct Layer {
  SceneSetup su;
  Frame fr;
};
Layer layer(double angle, double speed, std::vector<Gauge> gauges) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  test::one_open_stage(sc, "flow", 0.01);
  sc.h = 0.01;
  sc.dt = 1e-5;
  sc.origin = {-1.0, -1.0};
  sc.size = {2.0, 2.0};
  sc.bodies[0].box_min = {0.0, 0.0};
  sc.bodies[0].box_max = {0.4, 0.06};
  sc.gauges = std::move(gauges);
  Layer l{make_setup(sc), {}};
  const long n = l.su.particles.n;
  const double c = std::cos(angle), s = std::sin(angle);
  l.fr.n = n;
  l.fr.dim = 2;
  l.fr.x.resize(2 * n);
  l.fr.v.resize(2 * n);
  for (long i = 0; i < n; ++i) {
    const double x = l.su.particles.x[i], y = l.su.particles.x[n + i];
    l.fr.x[i] = c * x + s * y;
    l.fr.x[n + i] = -s * x + c * y;
    l.fr.v[i] = speed * c;
    l.fr.v[n + i] = -speed * s;
  }
  return l;
}

Gauge gauge(const std::string& name, double s_along, double angle, double length) {
  const double c = std::cos(angle), s = std::sin(angle);
  Gauge g;
  g.name = name;
  g.from = {c * s_along, -s * s_along};  // on the layer's base, the line normal to it
  g.to = {g.from[0] + s * length, g.from[1] + c * length};
  g.width = 0.01;
  return g;
}

}  // namespace

// Level and on a 35-degree slope: the depth is the layer's, u its speed across the line, the
// density its mass over depth x width and the mass flux rho h u; the velocity along the line is 0.
TEST(Gauges, MeasureTheDepthSpeedAndDensityOfAUniformLayer) {
  for (double deg : {0.0, 35.0}) {
    const double a = deg * M_PI / 180;
    Layer l = layer(a, 0.8, {gauge("mid", 0.2, a, 0.3)});
    const double rho = l.su.particles.m[0] / (l.su.spacing * l.su.spacing);  // seeded: one point per spacing^2
    const auto rows = measure_gauges(l.fr, l.su, l.su.particles.m, 1.0, 0.5);
    ASSERT_EQ(rows.size(), 1u);
    const GaugeRow& r = rows[0];
    EXPECT_EQ(r.t, 1.0);
    EXPECT_EQ(r.t_flow, 0.5);
    EXPECT_NEAR(r.depth, 0.06, 1e-12) << deg << " deg";
    EXPECT_NEAR(r.u, 0.8, 1e-12);
    EXPECT_NEAR(r.u_along, 0.0, 1e-12);
    EXPECT_NEAR(r.density, rho, 1e-9 * rho);
    EXPECT_NEAR(r.mass_flux, rho * 0.06 * 0.8, 1e-9 * rho);
    EXPECT_EQ(r.points, 2 * 12);  // two columns of points in a 1 cm band, twelve rows
  }
}

// A grain thrown a few cells above the flow, and the line's far end beyond the layer's edge, do
// not change the reading; a gauge where no point lies reads zero, and the flow reversed reads -u.
TEST(Gauges, CountOnlyTheBodyOfTheFlowAndReadZeroWhereThereIsNone) {
  Layer l = layer(0.0, -0.5, {gauge("mid", 0.2, 0.0, 0.3), gauge("dry", 0.7, 0.0, 0.3)});
  const long n = l.fr.n;
  long top = 0;  // the highest point of the column at x ~ 0.2, lifted 5 cells higher
  for (long i = 0; i < n; ++i)
    if (std::abs(l.fr.x[i] - 0.2025) < 1e-9 && l.fr.x[n + i] > l.fr.x[n + top]) top = i;
  ASSERT_NEAR(l.fr.x[top], 0.2025, 1e-9);
  l.fr.x[n + top] += 0.05;
  const auto rows = measure_gauges(l.fr, l.su, l.su.particles.m, 0.0, 0.0);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_NEAR(rows[0].depth, 0.06, 1e-12);  // the other column still reaches the top
  EXPECT_EQ(rows[0].points, 2 * 12 - 1);
  EXPECT_NEAR(rows[0].u, -0.5, 1e-12);
  EXPECT_EQ(rows[1].points, 0);
  EXPECT_EQ(rows[1].depth, 0.0);
  EXPECT_EQ(rows[1].u, 0.0);
  EXPECT_EQ(rows[1].density, 0.0);
}
