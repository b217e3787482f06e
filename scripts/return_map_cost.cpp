// Cost of the constitutive update on the shared random states (tests/constitutive/random_states.hpp):
// residual evaluations per update (UpdateInfo::substeps of the return map) in double and float,
// for the largest strain increments 1e-3, 1e-2 and 1e-1. Host only, no project build needed:
//   g++ -O2 -std=c++17 -I constitutive/include -I tests/constitutive -I tests -isystem /usr/include/eigen3 \
//       scripts/return_map_cost.cpp -o /tmp/return_map_cost && /tmp/return_map_cost
// (docs/benchmarks.md and docs/constitutive.md quote its output before and after a change.)
#include <algorithm>
#include <cstdio>
#include <vector>

#include "random_states.hpp"

using namespace granflow;

template <class S>
void report(const std::vector<test::RandomCase>& cases, const char* name) {
  const PhaseTransitionParams<S> p = params_cast<S>(test::table3_collapse());
  std::vector<int> ev;
  long unconverged = 0;
  for (const auto& c : cases) {
    typename PhaseTransitionModel<S>::State st;
    st.sigma_f = c.st.sigma_f.template cast<S>();
    st.e = S(c.st.e);
    st.eps_pd = S(c.st.eps_pd);
    st.s = S(c.st.s);
    Mat3<S> sig;
    const UpdateInfo inf = PhaseTransitionModel<S>::update(p, st, c.L.template cast<S>(), S(c.dt), sig);
    ev.push_back(inf.substeps);
    if (inf.flags & info::kReturnUnconverged) ++unconverged;
  }
  std::vector<int> s = ev;
  std::sort(s.begin(), s.end());
  double mean = 0;
  for (int x : ev) mean += x;
  mean /= double(ev.size());
  const long over20 = std::count_if(ev.begin(), ev.end(), [](int x) { return x > 20; });
  std::printf("%-7s mean %.2f  p99 %d  p99.9 %d  max %d  above 20: %ld  unconverged: %ld\n", name, mean,
              s[s.size() * 99 / 100], s[s.size() * 999 / 1000], s.back(), over20, unconverged);
}

int main() {
  for (double log_strain : {-3.0, -2.0, -1.0}) {
    const auto cases = test::random_cases(200000, log_strain, 0xabcdefull + static_cast<long>(log_strain * 10));
    std::printf("largest strain increment 1e%g (200,000 random states)\n", log_strain);
    report<double>(cases, "double");
    report<float>(cases, "float");
  }
}
