#include <granflow/io/parameter_set.hpp>
#include <granflow/io/share.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include <granflow/io/toml_reader.hpp>

namespace granflow::io {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// phi_c in degrees as read: of the degree values that give phi_c (times kDeg), the one with the
// fewest significant digits, so phi_c_deg = 30 reads back as 30, not 29.999999999999996.
double degrees_of(double phi_c) {
  const double deg = phi_c / kDeg;
  char buf[32];
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, deg);
    const double d = std::strtod(buf, nullptr);
    if (d * kDeg == phi_c) return d;
  }
  return deg;
}

FrictionalParams<double> read_frictional(TomlTable& t) {
  FrictionalParams<double> f;
  f.K0 = t.number("K0", Bounds::positive());
  f.nu = t.number("nu", {-1.0, 0.5, true, true});
  f.n = t.number("n", Bounds::closed(0.0, 1.0));
  f.phi_c = t.number("phi_c_deg", Bounds::open(0.0, 90.0)) * kDeg;
  f.e_ref = t.number("e_ref", Bounds::open(0.0, kVoidRatioMax));
  f.lambda_c = t.number("lambda_c", Bounds::non_negative());
  f.xi = t.number("xi", Bounds::positive());
  f.A_d = t.number("A_d", Bounds::non_negative());
  f.k_p = t.number("k_p", Bounds::positive());
  f.n_p = t.number("n_p", Bounds::non_negative());
  f.n_d = t.number("n_d", Bounds::non_negative());
  f.p_at = t.number_or("p_at", f.p_at, Bounds::positive());
  t.finish();
  return f;
}

// Optional sections of [collisional] (docs/constitutive.md, "Options of the collisional part").
// Absent: MODEL.md's model.
void read_collisional_options(TomlTable& t, CollisionalParams<double>& c) {
  if (auto r = t.optional_table("restitution")) {
    c.restitution = r->choice("use", {"everywhere", "dissipation_only"}, "everywhere") == "dissipation_only"
                        ? RestitutionUse::DissipationOnly
                        : RestitutionUse::Everywhere;
    c.k_mu = r->number_or("friction_factor", c.k_mu, Bounds::non_negative());
    r->finish();
  }
  if (auto j = t.optional_table("jamming")) {
    const std::string model = j->choice("model", {"constant", "friction"}, "");
    if (model == "friction") {
      c.jamming_friction = true;
      c.V_sd_inf = j->number("V_sd_inf", Bounds::open(0.0, 1.0));
      if (!(c.V_sd_inf <= c.V_sd))
        j->fail("V_sd_inf", "must not exceed the frictionless V_sd = " + std::to_string(c.V_sd) +
                                " ([collisional] V_sd or e_sd with model = 'friction')");
      if (!(c.V_m < c.V_sd_inf))
        j->fail("V_sd_inf", "must exceed V_m = " + std::to_string(c.V_m) + " (V_m < V_sd(mu_p) for every mu_p)");
      c.mu_star = j->number("mu_star", Bounds::positive());
    }
    j->finish();
  }
  if (auto d = t.optional_table("dilute")) {
    c.dilute_usf = d->choice("model", {"navier_stokes", "uniform_shear"}, "") == "uniform_shear";
    d->finish();
  }
  if (auto l = t.optional_table("correlation_length")) {
    c.corr_c = l->number("c", Bounds::positive());
    l->finish();
  }
}

CollisionalParams<double> read_collisional(TomlTable& t) {
  CollisionalParams<double> c;
  c.rho_p = t.number("rho_p", Bounds::positive());
  c.d = t.number("d", Bounds::positive());
  const bool has_esd = t.has("e_sd"), has_vsd = t.has("V_sd");
  if (has_esd == has_vsd) t.fail(has_esd ? "V_sd" : "e_sd", "give exactly one of e_sd or V_sd");
  if (has_esd) {
    const double e_sd = t.number("e_sd", Bounds::positive());
    c.V_sd = 1.0 / (1.0 + e_sd);
    // e_sd below ~1e-16 rounds V_sd to 1 (found by fuzzing: the set loaded, but could not be
    // read back once written with V_sd = 1).
    if (!(c.V_sd < 1.0)) {
      std::ostringstream os;
      os << "gives V_sd = 1/(1 + e_sd) = " << c.V_sd << ", which must be below 1 (e_sd = " << e_sd << " is too small)";
      t.fail("e_sd", os.str());
    }
  } else
    c.V_sd = t.number("V_sd", Bounds::open(0.0, 1.0));
  c.V_m = t.number("V_m", Bounds::open(0.0, 1.0));
  if (!(c.V_m < c.V_sd)) t.fail("V_m", "must be below V_sd = " + std::to_string(c.V_sd));
  c.eps_n = t.number("eps_n", Bounds::closed(0.0, 1.0));
  c.mu_p = t.number("mu_p", Bounds::non_negative());
  read_collisional_options(t, c);
  const double alpha = effective_restitution(c);
  if (!(alpha > -1.0 && alpha <= 1.0)) {
    std::ostringstream os;
    os << "effective restitution eps_n - " << c.k_mu << " mu_p exp(-3 mu_p) = " << alpha << " must lie in (-1, 1]";
    t.fail("mu_p", os.str());
  }
  t.finish();
  return c;
}

void read_numerics(TomlTable& t, ParameterSet& s) {
  if (s.frictional) {
    auto& f = *s.frictional;
    f.p_min = t.number_or("p_min", f.p_min, Bounds::positive());
    f.stol = t.number_or("stol", f.stol, Bounds::open(0.0, 1.0));
    f.ftol = t.number_or("ftol", f.ftol, Bounds::open(0.0, 1.0));
    f.max_substeps = static_cast<int>(t.integer_or("max_substeps", f.max_substeps, 1, 1000000));
  }
  if (s.collisional) s.collisional->vs_gap = t.number_or("vs_gap", s.collisional->vs_gap, Bounds::open(0.0, 0.1));
  t.finish();
}

}  // namespace

PhaseTransitionParams<double> ParameterSet::phase_transition() const {
  if (!frictional || !collisional)
    throw InputError(where(file) + "the phase-transition model needs both [frictional] and [collisional]");
  return {*frictional, *collisional};
}

ParameterSet parse_parameter_set(TomlTable& root) {
  ParameterSet s;
  s.file = root.file();
  s.name = root.string_or("name", "");
  s.source = root.string_or("source", "");
  if (auto t = root.optional_table("frictional")) s.frictional = read_frictional(*t);
  if (auto t = root.optional_table("collisional")) s.collisional = read_collisional(*t);
  if (!s.frictional && !s.collisional)
    throw InputError(where(s.file) + "a parameter set needs a [frictional] or a [collisional] table (or both)");
  if (auto t = root.optional_table("initial")) {
    if (t->has("e0")) s.e0 = t->numbers("e0", Bounds::open(0.0, kVoidRatioMax));
    s.T0 = t->optional_number("T0", Bounds::non_negative());
    t->finish();
  }
  if (auto t = root.optional_table("numerics")) read_numerics(*t, s);
  root.finish();
  for (double e0 : s.e0) check_initial_void_ratio(s, e0, "'initial.e0'");
  return s;
}

void check_initial_void_ratio(const ParameterSet& s, double e0, const std::string& what) {
  std::ostringstream os;
  if (!(e0 > 0.0 && e0 < kVoidRatioMax)) {
    os << where(s.file) << what << ": e0 = " << e0 << " must be in (0, " << kVoidRatioMax << ")";
    throw InputError(os.str());
  }
  if (s.collisional) {
    const double Vs = 1.0 / (1.0 + e0);
    const double V_sd = jamming_fraction(*s.collisional);
    if (!(Vs < V_sd)) {
      os << where(s.file) << what << ": e0 = " << e0 << " gives V_s = " << Vs << " at or above V_sd = "
         << V_sd << " (e0 must exceed e_sd = " << 1.0 / V_sd - 1.0 << ")";
      throw InputError(os.str());
    }
  }
}

ParameterSet load_parameter_set(const std::string& name_or_path) {
  // error_code forms: a name the OS refuses (too long, ...) is "not found", not a filesystem_error.
  std::string path = name_or_path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    const std::string candidate = data_directory() + "/params/" + name_or_path + ".toml";
    if (std::filesystem::exists(candidate, ec)) {
      path = candidate;
    } else {
      std::string known;
      const std::string params = data_directory() + "/params";
      for (const auto& e : std::filesystem::directory_iterator(params, ec))
        if (e.path().extension() == ".toml") known += (known.empty() ? "" : ", ") + e.path().stem().string();
      // no shipped set at all: the data folder is not where it was looked for
      const std::string none = "; the shipped sets are looked for in " + params + ", which " +
                               (std::filesystem::is_directory(params, ec) ? "holds none" : "does not exist") + " (" +
                               data_directory_origin() +
                               "): set GRANFLOW_DATA_DIR to the absolute path of the shipped data folder "
                               "(docs/install.md)";
      throw InputError(where(name_or_path) + "no such file, and no parameter set of that name" +
                       (known.empty() ? none : " (shipped sets: " + known + ")"));
    }
  }
  const toml::table doc = TomlTable::parse_file(path);
  TomlTable root(doc, path);
  return parse_parameter_set(root);
}

ParameterSet parse_parameter_set_text(const std::string& text, const std::string& name) {
  const toml::table doc = TomlTable::parse_text(text, name);
  TomlTable root(doc, name);
  return parse_parameter_set(root);
}

void apply_override(ParameterSet& set, const std::string& assignment, const std::string& origin) {
  const std::string who = origin + " '" + assignment + "': ";
  const auto eq = assignment.find('=');
  // the last dot before '=' ends the section: "collisional.jamming.mu_star=0.3" sets a key of an option table
  const auto dot = eq == std::string::npos ? std::string::npos : assignment.rfind('.', eq);
  if (eq == std::string::npos || dot == std::string::npos || dot > eq)
    throw InputError(who + "expected section.key=value, e.g. frictional.phi_c_deg=31");
  const std::string section = assignment.substr(0, dot);
  const std::string key = assignment.substr(dot + 1, eq - dot - 1);
  const std::string value = assignment.substr(eq + 1);
  // Re-serialise the set, change one value and parse again: the same validation applies.
  std::string text = format_parameter_set(set);
  toml::table doc;
  try {
    doc = toml::parse(std::string_view(text), std::string_view("<override>"));
    toml::table* tbl = &doc;
    for (std::size_t a = 0; tbl && a <= section.size();) {
      const std::size_t b = std::min(section.find('.', a), section.size());
      tbl = (*tbl)[section.substr(a, b - a)].as_table();
      a = b + 1;
    }
    if (!tbl) throw InputError(who + "the set has no [" + section + "] table");
    // A bare word is a string, as for scene keys (mpm/src/scene/scene_file.cpp parse_value).
    const bool bare_word = !value.empty() && value.find_first_of("\"'[]{}=#\\ \t\r\n") == std::string::npos;
    toml::table parsed;
    try {
      parsed = toml::parse(std::string_view("v = " + value), std::string_view("<override>"));
    } catch (const toml::parse_error&) {
      if (!bare_word) throw;
      parsed = toml::parse(std::string_view("v = \"" + value + "\""), std::string_view("<override>"));
    }
    if (section == "collisional" && (key == "e_sd" || key == "V_sd")) {
      tbl->erase("e_sd");
      tbl->erase("V_sd");
    }
    tbl->insert_or_assign(key, *parsed.get("v"));
  } catch (const toml::parse_error& err) {
    throw InputError(who + std::string(err.description()));
  }
  // Positions in the re-serialised text mean nothing to the user: messages name the assignment.
  const std::string tag = "<override>";
  TomlTable root(doc, tag);
  ParameterSet updated;
  try {
    updated = parse_parameter_set(root);
  } catch (const InputError& e) {
    std::string msg = e.what();
    if (msg.rfind(tag, 0) == 0) {
      std::size_t at = tag.size();
      while (at < msg.size() && (msg[at] == ':' || std::isdigit(static_cast<unsigned char>(msg[at])))) ++at;
      if (at < msg.size() && msg[at] == ' ') ++at;
      msg = msg.substr(at);
    }
    throw InputError(who + msg);
  }
  updated.file = set.file;
  set = updated;
}

std::string format_parameter_set(const ParameterSet& s) {
  std::ostringstream os;
  os << std::setprecision(17);
  // A TOML basic string: quote and backslash escaped, control characters as \uXXXX (a name
  // read from a file may hold them: written raw they made the output unreadable; found by fuzzing).
  auto q = [](const std::string& v) {
    std::string out = "\"";
    for (char c : v) {
      const auto u = static_cast<unsigned char>(c);
      if (c == '"' || c == '\\') {
        out += '\\';
        out += c;
      } else if (u < 0x20 || u == 0x7F) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\u%04X", u);
        out += buf;
      } else {
        out += c;
      }
    }
    return out + "\"";
  };
  if (!s.name.empty()) os << "name = " << q(s.name) << "\n";
  if (!s.source.empty()) os << "source = " << q(s.source) << "\n";
  if (s.frictional) {
    const auto& f = *s.frictional;
    os << "\n[frictional]\nK0 = " << f.K0 << "\nnu = " << f.nu << "\nn = " << f.n << "\nphi_c_deg = " << degrees_of(f.phi_c)
       << "\ne_ref = " << f.e_ref << "\nlambda_c = " << f.lambda_c << "\nxi = " << f.xi << "\nA_d = " << f.A_d
       << "\nk_p = " << f.k_p << "\nn_p = " << f.n_p << "\nn_d = " << f.n_d << "\np_at = " << f.p_at << "\n";
  }
  if (s.collisional) {
    const auto& c = *s.collisional;
    os << "\n[collisional]\nrho_p = " << c.rho_p << "\nd = " << c.d << "\nV_sd = " << c.V_sd << "\nV_m = " << c.V_m
       << "\neps_n = " << c.eps_n << "\nmu_p = " << c.mu_p << "\n";
    // options: written only where set, so a set without them reads back (and hashes) as before
    if (c.restitution == RestitutionUse::DissipationOnly || c.k_mu != 1.5) {
      os << "\n[collisional.restitution]\nuse = \""
         << (c.restitution == RestitutionUse::DissipationOnly ? "dissipation_only" : "everywhere") << "\"\n";
      if (c.k_mu != 1.5) os << "friction_factor = " << c.k_mu << "\n";
    }
    if (c.jamming_friction)
      os << "\n[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = " << c.V_sd_inf << "\nmu_star = " << c.mu_star
         << "\n";
    if (c.corr_c > 0) os << "\n[collisional.correlation_length]\nc = " << c.corr_c << "\n";
    if (c.dilute_usf) os << "\n[collisional.dilute]\nmodel = \"uniform_shear\"\n";
  }
  if (!s.e0.empty() || s.T0) {
    os << "\n[initial]\n";
    if (!s.e0.empty()) {
      os << "e0 = [";
      for (size_t i = 0; i < s.e0.size(); ++i) os << (i ? ", " : "") << s.e0[i];
      os << "]\n";
    }
    if (s.T0) os << "T0 = " << *s.T0 << "\n";
  }
  os << "\n[numerics]\n";
  if (s.frictional) {
    const auto& f = *s.frictional;
    os << "p_min = " << f.p_min << "\nstol = " << f.stol << "\nftol = " << f.ftol << "\nmax_substeps = " << f.max_substeps
       << "\n";
  }
  if (s.collisional) os << "vs_gap = " << s.collisional->vs_gap << "\n";
  return os.str();
}

}  // namespace granflow::io
