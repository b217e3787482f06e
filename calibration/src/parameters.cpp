#include "granflow/calibration/parameters.hpp"

#include <cmath>
#include <functional>
#include <map>

#include <granflow/io/input_error.hpp>

namespace granflow::calibration {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

struct Accessor {
  std::function<double(const io::ParameterSet&)> get;
  std::function<void(io::ParameterSet&, double)> set;
};

#define GF_FRICTIONAL(field) \
  Accessor { [](const io::ParameterSet& s) { return s.frictional->field; }, [](io::ParameterSet& s, double v) { s.frictional->field = v; } }
#define GF_COLLISIONAL(field) \
  Accessor { [](const io::ParameterSet& s) { return s.collisional->field; }, [](io::ParameterSet& s, double v) { s.collisional->field = v; } }

const std::map<std::string, Accessor>& accessors() {
  static const std::map<std::string, Accessor> table = {
      {"frictional.K0", GF_FRICTIONAL(K0)},
      {"frictional.nu", GF_FRICTIONAL(nu)},
      {"frictional.n", GF_FRICTIONAL(n)},
      {"frictional.phi_c_deg",
       {[](const io::ParameterSet& s) { return s.frictional->phi_c / kDeg; },
        [](io::ParameterSet& s, double v) { s.frictional->phi_c = v * kDeg; }}},
      {"frictional.e_ref", GF_FRICTIONAL(e_ref)},
      {"frictional.lambda_c", GF_FRICTIONAL(lambda_c)},
      {"frictional.xi", GF_FRICTIONAL(xi)},
      {"frictional.A_d", GF_FRICTIONAL(A_d)},
      {"frictional.k_p", GF_FRICTIONAL(k_p)},
      {"frictional.n_p", GF_FRICTIONAL(n_p)},
      {"frictional.n_d", GF_FRICTIONAL(n_d)},
      {"collisional.rho_p", GF_COLLISIONAL(rho_p)},
      {"collisional.d", GF_COLLISIONAL(d)},
      {"collisional.V_sd", GF_COLLISIONAL(V_sd)},
      {"collisional.e_sd",
       {[](const io::ParameterSet& s) { return 1.0 / s.collisional->V_sd - 1.0; },
        [](io::ParameterSet& s, double v) { s.collisional->V_sd = 1.0 / (1.0 + v); }}},
      {"collisional.V_m", GF_COLLISIONAL(V_m)},
      {"collisional.eps_n", GF_COLLISIONAL(eps_n)},
      {"collisional.mu_p", GF_COLLISIONAL(mu_p)},
      {"collisional.restitution.friction_factor", GF_COLLISIONAL(k_mu)},
      {"collisional.jamming.V_sd_inf", GF_COLLISIONAL(V_sd_inf)},
      {"collisional.jamming.mu_star", GF_COLLISIONAL(mu_star)},
      {"collisional.correlation_length.c", GF_COLLISIONAL(corr_c)},
  };
  return table;
}

#undef GF_FRICTIONAL
#undef GF_COLLISIONAL

// Per-test initial void ratio of experiment NAME: "test.e0@NAME" (job: key = "test.e0", experiment = NAME).
constexpr const char* kTestE0 = "test.e0@";
bool is_test_e0(const std::string& key) { return key.rfind(kTestE0, 0) == 0 && key.size() > 8; }

const Accessor& find(const io::ParameterSet& set, const std::string& key) {
  std::string why;
  if (!parameter_addressable(set, key, why)) throw io::InputError(why);
  return accessors().at(key);
}

}  // namespace

const std::vector<std::string>& settable_keys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const auto& [name, acc] : accessors()) k.push_back(name);
    return k;
  }();
  return keys;
}

bool parameter_addressable(const io::ParameterSet& set, const std::string& key, std::string& why) {
  if (is_test_e0(key)) return true;
  if (!accessors().count(key)) {
    why = "'" + key + "' is not a parameter; allowed: ";
    for (size_t i = 0; i < settable_keys().size(); ++i) why += (i ? ", " : "") + settable_keys()[i];
    return false;
  }
  const bool frictional = key.rfind("frictional.", 0) == 0;
  if (frictional ? !set.has_frictional() : !set.has_collisional()) {
    why = "'" + key + "': the starting parameter set has no [" + (frictional ? "frictional" : "collisional") + "] table";
    return false;
  }
  // an option's constant: only where the start set switches the option on
  const auto& c = set.collisional;
  if ((key.rfind("collisional.jamming.", 0) == 0 && !c->jamming_friction) ||
      (key.rfind("collisional.correlation_length.", 0) == 0 && !(c->corr_c > 0))) {
    why = "'" + key + "': the starting parameter set has no [" + key.substr(0, key.rfind('.')) +
          "] option (docs/constitutive.md, \"Options of the collisional part\")";
    return false;
  }
  return true;
}

double get_parameter(const io::ParameterSet& set, const std::string& key) {
  if (is_test_e0(key)) {
    const auto it = set.test_e0.find(key.substr(8));
    if (it == set.test_e0.end()) throw io::InputError("'" + key + "': no initial void ratio set for this experiment");
    return it->second;
  }
  return find(set, key).get(set);
}

void set_parameter(io::ParameterSet& set, const std::string& key, double value) {
  if (is_test_e0(key)) {
    set.test_e0[key.substr(8)] = value;
    return;
  }
  find(set, key).set(set, value);
}

}  // namespace granflow::calibration
