// Numerical guards of the element driver: which quantity of a state is non-finite or
// inadmissible, or whether a reported stress lies outside the yield surface, said in words with
// its value and the allowed range (for error messages).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <utility>

#include <granflow/constitutive.hpp>

namespace granflow::elementtest::detail {

// The first offending quantity as "name = value (allowed ...)", or "" when the state is
// admissible. sf: frictional stress [Pa]; s = sqrt(T) [m/s]. `p_floor` [Pa]: how far the
// frictional mean pressure may fall below the tension cut-off p_f = 0 (events stop it there;
// far below means the cut-off was missed; -inf: unchecked). `s_floor` [m/s]: integration error
// allowed on s below 0. Order: e and T first (the usual root cause), then the rest.
inline std::string inadmissible_state(const Mat3<double>& sf, double eps_pd, double e, double s, double gamma,
                                      double eps_v, double eps_a, double p_floor, double s_floor = 0.0) {
  std::ostringstream os;
  os.precision(10);
  if (!std::isfinite(e) || !(e > 0 && e < kVoidRatioMax)) {
    os << "e = " << e << " (allowed: 0 < e < " << kVoidRatioMax << ")";
    return os.str();
  }
  if (!std::isfinite(s)) {
    os << "T = " << s * s << " m2/s2 (must be finite)";
    return os.str();
  }
  if (s < s_floor) {  // s < 0: a temperature that went through zero
    os << "T < 0 (sqrt(T) = " << s << " m/s; allowed: T >= 0)";
    return os.str();
  }
  const char* names[6] = {"sigma_f_xx", "sigma_f_yy", "sigma_f_zz", "sigma_f_xy", "sigma_f_yz", "sigma_f_xz"};
  const double c[6] = {sf(0, 0), sf(1, 1), sf(2, 2), sf(0, 1), sf(1, 2), sf(0, 2)};
  for (int i = 0; i < 6; ++i)
    if (!std::isfinite(c[i])) {
      os << names[i] << " = " << c[i] << " Pa (must be finite)";
      return os.str();
    }
  const std::pair<const char*, double> rest[] = {{"eps_pd", eps_pd}, {"gamma", gamma}, {"eps_v", eps_v}, {"eps_a", eps_a}};
  for (const auto& [n, v] : rest)
    if (!std::isfinite(v)) {
      os << n << " = " << v << " (must be finite)";
      return os.str();
    }
  const double p = mean_pressure(sf);
  if (p < p_floor) {
    os << "p_f = " << p << " Pa, far below the tension cut-off p_f = 0 (allowed: p_f >= " << p_floor << " Pa)";
    return os.str();
  }
  return "";
}

// Yield-surface tolerance of reported results, on f = q_f / max(p_f, p_min) - g M_p h, a stress
// ratio (so relative to p_f): the band 100 ftol + 1e-6 in which the library's substepping counts
// a state as on the surface (ftol_load of frictional_increment, frictional.hpp). The return map
// converges to |f| <= ftol (1e3 ftol at round-off on the pressure floor), and CVODE's plastic
// mode projects onto f = 0 except at the cone vertex q_f <= 1e-6 p_f, where f <= q_f / p_f stays
// inside the band too.
inline double yield_guard_tolerance(const FrictionalParams<double>& mp) { return 100.0 * mp.ftol + 1e-6; }

// "" when the frictional stress sf [Pa] lies on or inside the yield surface within
// yield_guard_tolerance, else its q_f, p_f, stress ratio and the allowed ratio and q_f in words.
template <LodeShape L>
std::string outside_yield_surface(const FrictionalParams<double>& mp, const Mat3<double>& sf, double eps_pd,
                                  double e) {
  const YieldState<double> y = yield_state<L>(mp, sf, eps_pd, e, Mat3<double>::Zero());
  const double tol = yield_guard_tolerance(mp);
  if (y.f <= tol) return "";
  const double p = mean_pressure(sf), pe = std::max(p, mp.p_min);
  const double allowed = y.Gm * y.h + tol;
  std::ostringstream os;
  os.precision(10);
  os << "q_f = " << deviatoric_q(sf) << " Pa at p_f = " << p << " Pa lies outside the yield surface: q_f / "
     << (p > mp.p_min ? "p_f" : "p_min") << " = " << y.r << " (allowed: <= g M_p h + tol = " << y.Gm * y.h
     << " + " << tol << " = " << allowed << ", i.e. q_f <= " << allowed * pe << " Pa)";
  return os.str();
}

// The error and warning bits of UpdateInfo::flags in words.
inline std::string update_flags_text(std::uint32_t flags) {
  std::string s;
  auto add = [&](std::uint32_t bit, const char* what) {
    if (flags & bit) s += (s.empty() ? "" : "; ") + std::string(what);
  };
  add(info::kNonFinite, "a non-finite value was produced");
  add(info::kInadmissible, "inadmissible input state (stress or eps_pd not finite, eps_pd < 0, e <= 0, e >= 2.97 or T < 0)");
  add(info::kSubstepLimit, "substep budget exhausted");
  add(info::kReturnUnconverged, "return map unconverged (last iterate kept)");
  return s.empty() ? "flags " + std::to_string(flags) : s;
}

}  // namespace granflow::elementtest::detail
