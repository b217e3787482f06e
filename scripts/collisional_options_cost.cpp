// Cost of the collisional options (issue 25) on the CPU: ns per update of the phase-transition
// model and of the collisional part alone, on 20,000 random points (best of 15 passes), for
//   ./cost 0 [0|1]  options off (MODEL.md's model),  ./cost 1 [0|1]  the chosen options on
// (second argument 1: collisional part only). Host only, no project build needed:
//   g++ -O3 -DNDEBUG -std=c++17 -DNEW -I constitutive/include -isystem /usr/include/eigen3 \
//       scripts/collisional_options_cost.cpp -o /tmp/cost
// Without -DNEW and with -I pointing at an older constitutive/include it times the code before
// the options (docs/benchmarks.md, "Collisional options").
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>
#include <granflow/constitutive.hpp>
using namespace granflow;
int main(int argc, char** argv) {
  const bool opts = argc > 1 && argv[1][0] == '1';
  const bool coll_only = argc > 2 && argv[2][0] == '1';
  PhaseTransitionParams<double> p;
  auto& f = p.f;
  f.K0 = 120; f.nu = 0.2; f.n = 0.5; f.phi_c = 19.8 * M_PI / 180; f.e_ref = 0.977; f.lambda_c = 0.0596;
  f.xi = 0.365; f.A_d = 0.7; f.k_p = 0.0044; f.n_p = 2.4; f.n_d = 2.9; f.p_at = 101.3e3;
  auto& c = p.c;
  c.rho_p = 2650; c.d = 1.25e-3; c.V_sd = 1.0 / 1.62; c.V_m = 0.4; c.eps_n = 0.6; c.mu_p = 0.2;
#ifdef NEW
  if (opts) { c.V_sd = 0.646; c.V_m = 0.244; c.jamming_friction = true; c.V_sd_inf = 0.5815; c.mu_star = 0.171;
              c.dilute_usf = true; c.restitution = RestitutionUse::DissipationOnly; }
#endif
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  const int N = 20000;
  std::vector<PhaseTransitionState<double>> st0(N);
  std::vector<Mat3<double>> L(N);
  for (int i = 0; i < N; ++i) {
    st0[i].e = 0.75 + 0.2 * (u(rng) + 1);
    st0[i].s = 1e-3 * (u(rng) + 1);
    Mat3<double> s; s << -2e3, 100 * u(rng), 0, 100 * u(rng), -2e3, 0, 0, 0, -2e3;
    st0[i].sigma_f = 0.5 * (s + s.transpose());
    for (int a = 0; a < 3; ++a) for (int b = 0; b < 3; ++b) L[i](a, b) = (a < 2 && b < 2) ? 10 * u(rng) : 0;
  }
  double best = 1e9, sink = 0;
  for (int rep = 0; rep < 15; ++rep) {
    auto st = st0;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < N; ++i) {
      Mat3<double> sig;
      if (coll_only) {
        CollisionalState<double> cs{st[i].e, st[i].s};
        collisional_update(c, cs, L[i], 1e-4, sig);
      } else {
        PhaseTransitionModel<double>::update(p, st[i], L[i], 1e-4, sig);
      }
      sink += sig(0, 1);
    }
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    best = std::min(best, t);
  }
  std::printf("%.1f ns/update (sink %g)\n", best / N * 1e9, sink);
}
