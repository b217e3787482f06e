// The Abaqus UMAT of the frictional-only and the phase-transition models (docs/umat.md).
//
// One increment: the stress Abaqus hands in is already rotated by DROT (its Jaumann/Hughes-
// Winget rotation of the whole increment), so the UMAT adds the material response only: it calls
// the models' update (Model::update, the MPM's) with the velocity gradient D = DSTRAN / DTIME,
// which has no spin, so that update's half-step rotations are the identity. The library itself
// rotates by half steps around the material increment (Strang splitting, frictional/update.hpp);
// the two schemes agree to first order in the rotation per increment (docs/umat.md).
// The tangent DDSDDE is a forward-difference tangent (the return map does not give one).
#include <granflow/umat.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <set>
#include <sstream>
#include <string>

#include <granflow/constitutive.hpp>
#include <granflow/io/input_error.hpp>
#include <granflow/io/parameter_set.hpp>

#define GRANFLOW_UMAT_API extern "C" __attribute__((visibility("default")))

namespace {

using namespace granflow;
using M3 = Mat3<double>;
constexpr LodeShape kLode = LodeShape::SmoothMohrCoulomb;
using Frictional = FrictionalModel<double, kLode>;
using PhaseTransition = PhaseTransitionModel<double, kLode>;

// PROPS, in order (1-based as in the input file). 1: model; 2-13: [frictional] of a parameter
// set; 14: e0; 15-20: [collisional]; 21: T0.
constexpr const char* kPropNames[] = {"model", "K0",  "nu",    "n",    "phi_c_deg", "e_ref", "lambda_c",
                                      "xi",    "A_d", "k_p",   "n_p",  "n_d",       "p_at",  "e0",
                                      "rho_p", "d",   "V_sd",  "V_m",  "eps_n",     "mu_p",  "T0"};
// STATEV, 1-based: the layout of docs/umat.md.
enum Statev { kE = 0, kEpsPd, kT, kFlags, kPf, kQf, kKcol, kSigmaC };  // kSigmaC: 6 values (11 22 33 12 13 23)

// Strain perturbation of the numerical tangent (docs/umat.md, "Tangent").
constexpr double kTangentStep = 1e-8;
// PNEWDT asked for after a failed update or bad input.
constexpr double kCutback = 0.25;

struct Material {
  int model = 0;
  PhaseTransitionParams<double> p;  // p.c unused by the frictional model
  double e0 = 0, T0 = 0;
};

thread_local std::string t_error;

struct Rejected {  // bad input or a failed update: the message and what to do
  std::string message;
};

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

// The parameter set of PROPS, read by the parameter-set reader (its bounds and messages). Each
// key stands on its own line, so the reader's "line k" is PROPS(k).
Material read_props(const double* props, int nprops) {
  if (nprops < 1) throw Rejected{"NPROPS = " + std::to_string(nprops) + ": PROPS(1) must name the model (1 frictional, 2 phase transition)"};
  const double m = props[0];
  const int need = m == GRANFLOW_UMAT_FRICTIONAL         ? GRANFLOW_UMAT_NPROPS_FRICTIONAL
                   : m == GRANFLOW_UMAT_PHASE_TRANSITION ? GRANFLOW_UMAT_NPROPS_PHASE_TRANSITION
                                                         : 0;
  if (need == 0)
    throw Rejected{"PROPS(1) model = " + fmt(m) + ": must be 1 (frictional only) or 2 (phase transition)"};
  if (nprops != need)
    throw Rejected{"NPROPS = " + std::to_string(nprops) + " but model " + fmt(m) + " takes " + std::to_string(need) +
                   " properties (docs/umat.md, PROPS)"};
  for (int k = 0; k < nprops; ++k)
    if (!std::isfinite(props[k])) throw Rejected{"PROPS(" + std::to_string(k + 1) + ") " + kPropNames[k] + " is not finite"};
  // Line k of the text holds PROPS(k); line 1 is the model (a comment for the reader).
  std::ostringstream t;
  t.precision(17);
  t << "# model\n";
  for (int k = 1; k <= 12; ++k) t << "frictional." << kPropNames[k] << " = " << props[k] << "\n";
  t << "# e0\n";
  if (need == GRANFLOW_UMAT_NPROPS_PHASE_TRANSITION)
    for (int k = 14; k <= 19; ++k) t << "collisional." << kPropNames[k] << " = " << props[k] << "\n";
  io::ParameterSet set;
  try {
    set = io::parse_parameter_set_text(t.str(), "PROPS");
  } catch (const io::InputError& e) {
    // "PROPS:5:24: 'frictional.phi_c_deg': ..." -> "PROPS(5) 'frictional.phi_c_deg': ...": the line is the index.
    std::string msg = e.what();
    if (msg.rfind("PROPS:", 0) == 0) {
      const std::size_t line_end = msg.find(':', 6);
      if (line_end != std::string::npos) {
        std::size_t rest = line_end;
        const std::size_t col_end = msg.find(':', line_end + 1);
        if (col_end != std::string::npos && col_end > line_end + 1 &&
            msg.find_first_not_of("0123456789", line_end + 1) == col_end)
          rest = col_end;  // drop the column
        msg = "PROPS(" + msg.substr(6, line_end - 6) + ")" + msg.substr(rest + 1);
      }
    }
    throw Rejected{msg};
  }
  Material mat;
  mat.model = static_cast<int>(m);
  mat.p.f = *set.frictional;
  mat.e0 = props[13];
  if (mat.model == GRANFLOW_UMAT_PHASE_TRANSITION) {
    mat.p.c = *set.collisional;
    mat.T0 = props[20];
    if (!(mat.T0 >= 0)) throw Rejected{"PROPS(21) T0 = " + fmt(mat.T0) + ": must be >= 0"};
  }
  set.file.clear();  // messages name PROPS(14), not a file
  try {
    io::check_initial_void_ratio(set, mat.e0, "PROPS(14) e0");
  } catch (const io::InputError& e) {
    const std::string m = e.what();
    throw Rejected{m.rfind(": ", 0) == 0 ? m.substr(2) : m};
  }
  return mat;
}

// Refuses a NaN or infinite value of an Abaqus array: "NAME(k) = nan is not finite".
void require_finite(const double* v, int n, const char* name, int first = 1) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(v[k]))
      throw Rejected{std::string(name) + "(" + std::to_string(first + k) + ") = " + fmt(v[k]) + " is not finite on entry"};
}

// The material of the last PROPS this thread saw (a UMAT is called with the same PROPS many times).
const Material& material(const double* props, int nprops) {
  thread_local std::array<double, GRANFLOW_UMAT_NPROPS_PHASE_TRANSITION> last{};
  thread_local int last_n = -1;
  thread_local Material mat;
  if (nprops == last_n && nprops <= int(last.size()) && std::memcmp(props, last.data(), sizeof(double) * nprops) == 0)
    return mat;
  mat = read_props(props, nprops);
  std::memcpy(last.data(), props, sizeof(double) * nprops);
  last_n = nprops;
  return mat;
}

// Abaqus order of tensor components: 11 22 33 12 (NTENS 4), then 13 23 (NTENS 6).
constexpr int kVoigt[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};

M3 tensor_of_stress(const double* v, int ntens) {
  M3 s = M3::Zero();
  for (int k = 0; k < ntens; ++k) s(kVoigt[k][0], kVoigt[k][1]) = s(kVoigt[k][1], kVoigt[k][0]) = v[k];
  return s;
}
// Strains: engineering shear (gamma = 2 eps) in STRAN and DSTRAN.
M3 tensor_of_strain(const double* v, int ntens) {
  M3 s = M3::Zero();
  for (int k = 0; k < ntens; ++k) {
    const double x = k < 3 ? v[k] : 0.5 * v[k];
    s(kVoigt[k][0], kVoigt[k][1]) = s(kVoigt[k][1], kVoigt[k][0]) = x;
  }
  return s;
}
void store_stress(const M3& s, double* v, int ntens) {
  for (int k = 0; k < ntens; ++k) v[k] = s(kVoigt[k][0], kVoigt[k][1]);
}
M3 column_major(const double* a) {
  M3 m;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) m(i, j) = a[3 * j + i];
  return m;
}

struct PointIn {  // the state at the start of the increment, in the rotated frame
  M3 sigma_f, sigma_c;  // frictional stress; collisional stress of the last increment
  double eps_pd, e, T;
};
struct PointOut {
  M3 sigma_f, sigma_c, stress;
  double eps_pd, e, T;
  UpdateInfo info;
};

// The material increment over the strain increment deps in time dt (no rotation).
PointOut increment(const Material& mat, const PointIn& in, const M3& deps, double dt) {
  PointOut o;
  o.sigma_c = mat.model == GRANFLOW_UMAT_FRICTIONAL ? M3::Zero() : in.sigma_c;
  if (mat.model == GRANFLOW_UMAT_FRICTIONAL || !(dt > 0)) {
    // Rate-independent: any dt gives the same increment, and DTIME = 0 (a zero increment) is
    // allowed; the phase-transition model's collisional part is then left as it was (T kept).
    Frictional::State st{in.sigma_f, in.eps_pd, in.e};
    const double h = dt > 0 ? dt : 1.0;
    o.info = Frictional::update(mat.p.f, st, deps / h, h, o.stress);
    o.stress += o.sigma_c;
    o.sigma_f = st.sigma;
    o.eps_pd = st.eps_pd;
    o.e = st.e;
    o.T = in.T;
  } else {
    PhaseTransition::State st;
    st.sigma_f = in.sigma_f;
    st.eps_pd = in.eps_pd;
    st.e = in.e;
    st.s = std::sqrt(in.T);
    o.info = PhaseTransition::update(mat.p, st, deps / dt, dt, o.stress);
    o.sigma_f = st.sigma_f;
    o.eps_pd = st.eps_pd;
    o.e = st.e;
    o.T = st.s * st.s;
    o.sigma_c = o.stress - st.sigma_f;
  }
  return o;
}

void report(const std::string& where, const std::string& message) {
  t_error = where + ": " + message;
  // Each distinct message once per process: a bad PROPS reaches every point of a mesh.
  static std::mutex mu;
  static std::set<std::string> said;
  std::lock_guard<std::mutex> lock(mu);
  if (said.insert(message).second) std::fprintf(stderr, "granflow umat: %s\n", t_error.c_str());
}

}  // namespace

GRANFLOW_UMAT_API const char* granflow_umat_last_error(void) { return t_error.c_str(); }

GRANFLOW_UMAT_API void umat_(double* stress, double* statev, double* ddsdde, double* sse, double* spd, double* scd,
                             double* rpl, double* ddsddt, double* drplde, double* drpldt, const double* stran,
                             const double* dstran, const double* time, const double* dtime, const double* temp,
                             const double* dtemp, const double* predef, const double* dpred, const char* cmname,
                             const int* ndi, const int* nshr, const int* ntens, const int* nstatv,
                             const double* props, const int* nprops, const double* coords, const double* drot,
                             double* pnewdt, const double* celent, const double* dfgrd0, const double* dfgrd1,
                             const int* noel, const int* npt, const int* layer, const int* kspt, const int* jstep,
                             const int* kinc, size_t cmname_len) {
  (void)sse, (void)spd, (void)scd, (void)stran, (void)time, (void)temp, (void)dtemp, (void)predef, (void)dpred;
  (void)coords, (void)celent, (void)dfgrd0, (void)dfgrd1, (void)layer, (void)kspt, (void)jstep, (void)kinc;
  const int n = *ntens;
  // No thermal coupling.
  *rpl = 0;
  *drpldt = 0;
  for (int k = 0; k < n; ++k) ddsddt[k] = drplde[k] = 0;
  std::string name(cmname, strnlen(cmname, cmname_len));
  while (!name.empty() && name.back() == ' ') name.pop_back();
  const std::string where = "material " + name + ", element " + std::to_string(*noel) + ", point " + std::to_string(*npt);
  try {
    if (*ndi != 3 || (*nshr != 1 && *nshr != 3) || n != *ndi + *nshr)
      throw Rejected{"NDI = " + std::to_string(*ndi) + ", NSHR = " + std::to_string(*nshr) + ", NTENS = " +
                     std::to_string(n) + ": only NTENS 4 (NDI 3, NSHR 1: plane strain, axisymmetric) and 6 (NDI 3, "
                     "NSHR 3: 3D) are supported (no plane stress)"};
    if (*nstatv < GRANFLOW_UMAT_NSTATV)
      throw Rejected{"NSTATV = " + std::to_string(*nstatv) + ": *DEPVAR needs at least " +
                     std::to_string(GRANFLOW_UMAT_NSTATV) + " (docs/umat.md, STATEV)"};
    const Material& mat = material(props, *nprops);
    // The increment and the state on entry: finite, admissible (state_check.hpp).
    if (!(*dtime >= 0) || !std::isfinite(*dtime))
      throw Rejected{"DTIME = " + fmt(*dtime) + ": must be finite and >= 0"};
    require_finite(dstran, n, "DSTRAN");
    require_finite(drot, 9, "DROT");
    require_finite(stress, n, "STRESS");
    require_finite(statev, 3, "STATEV");
    require_finite(statev + kSigmaC, 6, "STATEV", kSigmaC + 1);

    // The state at the start, in the frame Abaqus has rotated the stress into. The stored
    // collisional stress is a tensor state variable: rotated here by DROT, as Abaqus expects of a UMAT.
    const M3 R = column_major(drot);
    const M3 sigma_in = tensor_of_stress(stress, n);
    PointIn in;
    in.sigma_c = R * tensor_of_stress(statev + kSigmaC, 6) * R.transpose();
    in.sigma_f = sigma_in - in.sigma_c;
    if (statev[kE] == 0) {  // first increment: e0, T0 from PROPS, eps_pd putting the initial stress on f = 0
      in.e = mat.e0;
      in.T = mat.model == GRANFLOW_UMAT_PHASE_TRANSITION ? mat.T0 : 0.0;
      in.eps_pd = initial_plastic_strain<kLode>(mat.p.f, in.sigma_f, in.e);
      // A tension (p_f < 0) lies outside the cone of a cohesionless skeleton, as a stress
      // ratio above g M_p does; the update would set it to zero.
      if (!(in.eps_pd >= 0) || mean_pressure(in.sigma_f) < 0)
        throw Rejected{"the initial stress (p_f = " + fmt(mean_pressure(in.sigma_f)) + " Pa, q_f = " +
                       fmt(deviatoric_q(in.sigma_f)) + " Pa) lies outside the yield surface at e0 = " + fmt(in.e) +
                       (mean_pressure(in.sigma_f) < 0 ? " (a tension: p_f < 0)" : "")};
    } else {
      in.e = statev[kE];
      in.eps_pd = statev[kEpsPd];
      in.T = statev[kT];
      switch (frictional_state_fault(in.sigma_f, in.eps_pd, in.e)) {
        case StateFault::PlasticStrain:
          throw Rejected{"STATEV(2) eps_pd = " + fmt(in.eps_pd) + " on entry: must be >= 0"};
        case StateFault::VoidRatio:
          throw Rejected{"STATEV(1) e = " + fmt(in.e) + " on entry: must be in (0, " + fmt(kVoidRatioMax) + ")"};
        case StateFault::Stress:
          throw Rejected{"the frictional stress STRESS - STATEV(8:13) overflows (not finite) on entry"};
        default: break;
      }
      if (!admissible_sqrt_temperature(std::sqrt(in.T)))
        throw Rejected{"STATEV(3) T = " + fmt(in.T) + " on entry: must be >= 0"};
    }
    const M3 deps = tensor_of_strain(dstran, n);
    const PointOut o = increment(mat, in, deps, *dtime);
    if (!o.info.ok()) {
      std::ostringstream os;
      os.precision(6);
      os << "update failed (flags " << o.info.flags << ") at p_f = " << mean_pressure(in.sigma_f)
         << " Pa, e = " << in.e << ", T = " << in.T << ": increment rejected, PNEWDT = " << kCutback;
      throw Rejected{os.str()};
    }

    // Tangent: forward differences of the total stress in each strain component (engineering
    // shear), from the same start state; a failed perturbed update is retried backwards.
    std::array<double, 36> D{};
    for (int j = 0; j < n; ++j) {
      for (double sign : {1.0, -1.0}) {
        std::array<double, 6> d{};
        std::copy(dstran, dstran + n, d.begin());
        const double h = sign * kTangentStep;
        d[j] += h;
        const PointOut oj = increment(mat, in, tensor_of_strain(d.data(), n), *dtime);
        if (!oj.info.ok()) continue;
        for (int i = 0; i < n; ++i)
          D[j * n + i] = (oj.stress(kVoigt[i][0], kVoigt[i][1]) - o.stress(kVoigt[i][0], kVoigt[i][1])) / h;
        break;
      }
    }
    std::copy(D.begin(), D.begin() + n * n, ddsdde);

    store_stress(o.stress, stress, n);
    statev[kE] = o.e;
    statev[kEpsPd] = o.eps_pd;
    statev[kT] = o.T;
    statev[kFlags] = static_cast<double>(o.info.flags);
    statev[kPf] = mean_pressure(o.sigma_f);
    statev[kQf] = deviatoric_q(o.sigma_f);
    statev[kKcol] = collisional_share(deviatoric_q(o.sigma_c), deviatoric_q(o.sigma_f));
    store_stress(o.sigma_c, statev + kSigmaC, 6);
    t_error.clear();
  } catch (const Rejected& r) {
    report(where, r.message);
    *pnewdt = kCutback;  // STRESS and STATEV as they came in
    for (int k = 0; k < n * n; ++k) ddsdde[k] = 0;
  } catch (const std::exception& e) {  // nothing may cross into Fortran
    report(where, std::string("internal error: ") + e.what());
    *pnewdt = kCutback;
    for (int k = 0; k < n * n; ++k) ddsdde[k] = 0;
  }
}
