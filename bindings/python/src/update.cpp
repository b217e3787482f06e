// granflow.update: the constitutive update (Model::update, the MPM's and the incremental
// element driver's) on many material points at once, on threads, without the GIL.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <thread>

#include <granflow/constitutive.hpp>

#include "common.hpp"
#include <granflow/io/input_error.hpp>

namespace granflow::python {

namespace {

using Arr = py::array_t<double, py::array::c_style | py::array::forcecast>;
using RowMat = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

enum class Kind { Frictional, Collisional, PhaseTransition };

// Flat views of the inputs and outputs; stride 0 broadcasts one value to every point.
struct Batch {
  long n = 0;
  const double *sig = nullptr, *eps = nullptr, *e = nullptr, *T = nullptr, *L = nullptr, *dt = nullptr;
  long L_stride = 9, dt_stride = 1;
  double *sig_o = nullptr, *eps_o = nullptr, *e_o = nullptr, *T_o = nullptr, *stress_o = nullptr;
  std::uint32_t* flags_o = nullptr;
};

Mat3<double> mat(const double* p) { return Eigen::Map<const RowMat>(p); }
void put(double* p, const Mat3<double>& m) {
  Eigen::Map<RowMat> out(p);
  out = m;
}

// State <-> arrays, per model (T is stored, the library carries s = sqrt(T)).
void load(FrictionalState<double>& st, const Batch& b, long i) {
  st.sigma = mat(b.sig + 9 * i);
  st.eps_pd = b.eps[i];
  st.e = b.e[i];
}
void store(const FrictionalState<double>& st, const Batch& b, long i) {
  put(b.sig_o + 9 * i, st.sigma);
  b.eps_o[i] = st.eps_pd;
  b.e_o[i] = st.e;
}
void load(CollisionalState<double>& st, const Batch& b, long i) {
  st.e = b.e[i];
  st.s = std::sqrt(b.T[i]);  // NaN for T < 0: the update reports the state inadmissible
}
void store(const CollisionalState<double>& st, const Batch& b, long i) {
  b.e_o[i] = st.e;
  b.T_o[i] = st.s * st.s;
}
void load(PhaseTransitionState<double>& st, const Batch& b, long i) {
  st.sigma_f = mat(b.sig + 9 * i);
  st.eps_pd = b.eps[i];
  st.e = b.e[i];
  st.s = std::sqrt(b.T[i]);
}
void store(const PhaseTransitionState<double>& st, const Batch& b, long i) {
  put(b.sig_o + 9 * i, st.sigma_f);
  b.eps_o[i] = st.eps_pd;
  b.e_o[i] = st.e;
  b.T_o[i] = st.s * st.s;
}
// A point whose update failed keeps its input state; its stress is NaN.
void keep(const Batch& b, long i) {
  if (b.sig) std::copy(b.sig + 9 * i, b.sig + 9 * i + 9, b.sig_o + 9 * i);
  if (b.eps) b.eps_o[i] = b.eps[i];
  b.e_o[i] = b.e[i];
  if (b.T) b.T_o[i] = b.T[i];
  std::fill(b.stress_o + 9 * i, b.stress_o + 9 * i + 9, std::numeric_limits<double>::quiet_NaN());
}

template <class Model>
void update_range(const typename Model::Params& p, const Batch& b, long i0, long i1) {
  for (long i = i0; i < i1; ++i) {
    typename Model::State st;
    load(st, b, i);
    Mat3<double> stress = Mat3<double>::Zero();
    const UpdateInfo inf = Model::update(p, st, mat(b.L + b.L_stride * i), b.dt[b.dt_stride * i], stress);
    b.flags_o[i] = inf.flags;
    if (inf.ok()) {
      store(st, b, i);
      put(b.stress_o + 9 * i, stress);
    } else {
      keep(b, i);
    }
  }
}

template <class Model>
void update_all(const typename Model::Params& p, const Batch& b, unsigned threads) {
  const long per = 512;  // points per thread at least
  const long nt = std::max(1L, std::min<long>(threads, (b.n + per - 1) / per));
  if (nt == 1) return update_range<Model>(p, b, 0, b.n);
  std::vector<std::thread> pool;
  const long chunk = (b.n + nt - 1) / nt;
  for (long t = 0; t < nt; ++t)
    pool.emplace_back([&, t] { update_range<Model>(p, b, t * chunk, std::min(b.n, (t + 1) * chunk)); });
  for (auto& th : pool) th.join();
}

Kind choose_kind(const io::ParameterSet& set, const std::string& model) {
  Kind k;
  if (model == "auto")
    k = set.has_frictional() && set.has_collisional() ? Kind::PhaseTransition
        : set.has_frictional()                         ? Kind::Frictional
                                                       : Kind::Collisional;
  else if (model == "frictional")
    k = Kind::Frictional;
  else if (model == "collisional")
    k = Kind::Collisional;
  else if (model == "phase_transition")
    k = Kind::PhaseTransition;
  else
    throw io::InputError("update: model '" + model + "': expected auto, frictional, collisional or phase_transition");
  if ((k != Kind::Collisional && !set.has_frictional()) || (k != Kind::Frictional && !set.has_collisional()))
    throw io::InputError(io::where(set.file) + "the " + model + " model needs a [" +
                         (set.has_frictional() ? "collisional" : "frictional") + "] table in the parameter set");
  return k;
}

std::vector<std::string> state_keys(Kind k) {
  switch (k) {
    case Kind::Frictional: return {"sigma_f", "eps_pd", "e"};
    case Kind::Collisional: return {"e", "T"};
    default: return {"sigma_f", "eps_pd", "e", "T"};
  }
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

std::string shape_text(const Arr& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// h as a C-contiguous float64 array (a copy where it is not one already). Arr::ensure() hides why a
// conversion failed: an array too large to copy is a MemoryError that says how large, anything
// else a TypeError naming `what`.
Arr float64_array(py::handle h, const std::string& what) {
  Arr a = Arr::ensure(h);
  if (a) return a;
  // a numeric array fails to convert only when its copy cannot be allocated
  if (py::isinstance<py::array>(h) &&
      std::string("biuf").find(py::reinterpret_borrow<py::array>(h).dtype().kind()) != std::string::npos) {
    const auto src = py::reinterpret_borrow<py::array>(h);
    const double gib = 8.0 * static_cast<double>(src.size()) / (1024.0 * 1024.0 * 1024.0);
    char size[32];
    std::snprintf(size, sizeof size, "%.3g", gib);
    PyErr_SetString(PyExc_MemoryError,
                    ("update: " + what + " has " + std::to_string(src.size()) + " elements; its float64 copy needs " +
                     size + " GiB, more than could be allocated: pass fewer points, or a C-contiguous float64 array "
                     "(used without a copy)").c_str());
    throw py::error_already_set();
  }
  throw py::type_error("update: " + what + " is not convertible to a float64 array");
}

py::dict update(py::handle params, const py::dict& state, py::handle grad_v, py::handle dt, const std::string& model,
                unsigned threads) {
  const io::ParameterSet set = params_arg(params);
  const Kind kind = choose_kind(set, model);
  const std::vector<std::string> keys = state_keys(kind);
  for (auto [k, v] : state) {
    const std::string key = py::str(k).cast<std::string>();
    if (std::find(keys.begin(), keys.end(), key) == keys.end())
      throw io::InputError("update: state key '" + key + "' is not part of the " + model + " state (" + join(keys) + ")");
  }
  std::map<std::string, Arr> in;
  for (const auto& key : keys) {
    if (!state.contains(key))
      throw io::InputError("update: state is missing '" + key + "' (the state has " + join(keys) + ")");
    in[key] = float64_array(state[py::str(key)], "state['" + key + "']");
  }
  const py::ssize_t n = in["e"].ndim() == 1 ? in["e"].shape(0) : -1;
  if (n < 0) throw io::InputError("update: state['e'] must be 1-D (one void ratio per point), got shape " + shape_text(in["e"]));
  for (const auto& key : keys) {
    const Arr& a = in[key];
    const bool tensor = key == "sigma_f";
    const bool ok = tensor ? a.ndim() == 3 && a.shape(0) == n && a.shape(1) == 3 && a.shape(2) == 3
                           : a.ndim() == 1 && a.shape(0) == n;
    if (!ok)
      throw io::InputError("update: state['" + key + "'] has shape " + shape_text(a) + ", expected " +
                           (tensor ? "(" + std::to_string(n) + ", 3, 3)" : "(" + std::to_string(n) + ",)"));
  }
  Arr L = float64_array(grad_v, "grad_v"), h = float64_array(dt, "dt");
  Batch b;
  b.n = n;
  if (L.ndim() == 2 && L.shape(0) == 3 && L.shape(1) == 3)
    b.L_stride = 0;
  else if (!(L.ndim() == 3 && L.shape(0) == n && L.shape(1) == 3 && L.shape(2) == 3))
    throw io::InputError("update: grad_v has shape " + shape_text(L) + ", expected (3, 3) or (" + std::to_string(n) +
                         ", 3, 3)");
  if (h.ndim() == 0)
    b.dt_stride = 0;
  else if (!(h.ndim() == 1 && h.shape(0) == n))
    throw io::InputError("update: dt has shape " + shape_text(h) + ", expected a number or (" + std::to_string(n) + ",)");
  for (py::ssize_t i = 0; i < h.size(); ++i)
    if (!(h.data()[i] > 0) || !std::isfinite(h.data()[i]))
      throw io::InputError("update: dt must be finite and > 0, got " + std::to_string(h.data()[i]));
  for (py::ssize_t i = 0; i < L.size(); ++i)
    if (!std::isfinite(L.data()[i])) {
      std::string at = std::to_string(i / 3 % 3) + ", " + std::to_string(i % 3);
      if (b.L_stride) at = std::to_string(i / 9) + ", " + at;
      throw io::InputError("update: grad_v[" + at + "] = " + std::to_string(L.data()[i]) + " is not finite");
    }
  b.L = L.data();
  b.dt = h.data();

  py::dict out;
  auto make = [&](const std::string& key, std::vector<py::ssize_t> shape) {
    Arr a(shape);
    out[py::str(key)] = a;
    return a.mutable_data();
  };
  b.e = in["e"].data();
  b.e_o = make("e", {n});
  if (in.count("sigma_f")) {
    b.sig = in["sigma_f"].data();
    b.sig_o = make("sigma_f", {n, 3, 3});
    b.eps = in["eps_pd"].data();
    b.eps_o = make("eps_pd", {n});
  }
  if (in.count("T")) {
    b.T = in["T"].data();
    b.T_o = make("T", {n});
  }
  b.stress_o = make("stress", {n, 3, 3});
  py::array_t<std::uint32_t> flags(n);
  b.flags_o = flags.mutable_data();
  out["flags"] = flags;
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  {
    py::gil_scoped_release nogil;
    switch (kind) {
      case Kind::Frictional: update_all<FrictionalModel<double>>(*set.frictional, b, threads); break;
      case Kind::Collisional: update_all<CollisionalModel<double>>(*set.collisional, b, threads); break;
      default: update_all<PhaseTransitionModel<double>>(set.phase_transition(), b, threads); break;
    }
  }
  py::array_t<bool> ok(n);
  for (py::ssize_t i = 0; i < n; ++i) ok.mutable_data()[i] = (b.flags_o[i] & info::kErrorMask) == 0;
  out["ok"] = ok;
  return out;
}

}  // namespace

void register_update(py::module_& m) {
  m.def("update", &update, py::arg("params"), py::arg("state"), py::arg("grad_v"), py::arg("dt"),
        py::arg("model") = "auto", py::arg("threads") = 0u,
        R"(One constitutive update of many material points (Model::update, the MPM's update).

params  ParameterSet, set name, path or dict.
state   dict of arrays for n points: sigma_f (n, 3, 3) frictional Cauchy stress [Pa], tension
        positive; eps_pd (n,); e (n,) void ratio; T (n,) granular temperature [m2/s2]. The
        frictional model takes sigma_f, eps_pd, e; the collisional e, T; the phase-transition
        model all four.
grad_v  velocity gradient L = dv/dx [1/s], (3, 3) for every point or (n, 3, 3); a displacement-
        gradient increment dU over the step is L = dU / dt.
dt      step [s], a number or (n,).
model   "auto" (both parts if the set has both), "frictional", "collisional", "phase_transition".
threads 0: all cores.

Returns a dict: the new state arrays (same keys), stress (n, 3, 3) total Cauchy stress, flags
(n,) uint32 (granflow.FLAGS) and ok (n,) bool. A point whose update failed (flags in
FLAG_ERROR_MASK) keeps its input state and gets a NaN stress; a point whose input state is
inadmissible (NaN or inf anywhere, eps_pd < 0, e outside (0, 2.97), T < 0) fails so, with the
flag "inadmissible". Bad arguments (shapes, keys, a non-finite grad_v or dt) raise InputError.)");
  py::dict flags;
  flags["tension_cutoff"] = info::kTensionCutoff;
  flags["pressure_floor"] = info::kPressureFloor;
  flags["vs_clamped"] = info::kVsClamped;
  flags["substep_limit"] = info::kSubstepLimit;
  flags["non_finite"] = info::kNonFinite;
  flags["inadmissible"] = info::kInadmissible;
  flags["return_unconverged"] = info::kReturnUnconverged;
  flags["plastic_return"] = info::kPlasticReturn;
  flags["floored_return"] = info::kFlooredReturn;
  flags["bracketed_return"] = info::kBracketedReturn;
  m.attr("FLAGS") = flags;
  m.attr("FLAG_ERROR_MASK") = info::kErrorMask;
}

}  // namespace granflow::python
