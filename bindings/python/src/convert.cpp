// Argument conversion shared by the binding sources.
#include <cmath>
#include <string>

#include "common.hpp"
#include <granflow/io/toml_reader.hpp>

namespace granflow::python {

std::string path_arg(py::handle h, const char* what) {
  if (py::isinstance<py::str>(h)) return h.cast<std::string>();
  if (py::hasattr(h, "__fspath__")) return py::module_::import("os").attr("fspath")(h).cast<std::string>();
  throw py::type_error(std::string(what) + ": expected a path (str or os.PathLike), got " +
                       py::str(py::type::of(h).attr("__name__")).cast<std::string>());
}

io::ParameterSet params_arg(py::handle h) {
  if (py::isinstance<io::ParameterSet>(h)) return h.cast<io::ParameterSet>();
  if (py::isinstance<py::dict>(h)) {
    const toml::table t = to_toml(h.cast<py::dict>(), "params");
    io::TomlTable root(t, "<dict>");
    return io::parse_parameter_set(root);
  }
  return io::load_parameter_set(path_arg(h, "params"));
}

std::vector<std::string> strings_arg(py::handle h, const char* what) {
  if (h.is_none()) return {};
  if (py::isinstance<py::str>(h)) return {h.cast<std::string>()};
  std::vector<std::string> out;
  for (py::handle x : py::iter(h)) {
    if (!py::isinstance<py::str>(x))
      throw py::type_error(std::string(what) + ": expected strings \"section.key=value\"");
    out.push_back(x.cast<std::string>());
  }
  return out;
}

namespace {

void append(toml::array& a, py::handle v, const std::string& where);

// One Python value as a TOML node handed to `put` (two instantiations: array and table; the
// recursion goes through append, so no lambda type nests).
template <class Put>
void put_value(py::handle v, const std::string& where, Put&& put) {
  if (py::isinstance<py::bool_>(v)) {
    put(toml::value<bool>(v.cast<bool>()));
  } else if (py::isinstance<py::str>(v)) {
    put(toml::value<std::string>(v.cast<std::string>()));
  } else if (py::isinstance<py::dict>(v)) {
    put(to_toml(v.cast<py::dict>(), where));
  } else if (py::isinstance<py::array>(v) || py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    py::object seq = py::isinstance<py::array>(v) ? v.attr("tolist")() : py::reinterpret_borrow<py::object>(v);
    toml::array a;
    std::size_t i = 0;
    for (py::handle x : py::iter(seq)) append(a, x, where + "[" + std::to_string(i++) + "]");
    put(std::move(a));
  } else if (py::hasattr(v, "__index__")) {  // int, NumPy integers
    put(toml::value<int64_t>(py::int_(py::reinterpret_borrow<py::object>(v)).cast<int64_t>()));
  } else if (py::hasattr(v, "__float__")) {  // float, NumPy floats
    put(toml::value<double>(py::float_(py::reinterpret_borrow<py::object>(v)).cast<double>()));
  } else {
    throw py::type_error(where + ": cannot be a TOML value (" +
                         py::str(py::type::of(v).attr("__name__")).cast<std::string>() + ")");
  }
}

void append(toml::array& a, py::handle v, const std::string& where) {
  put_value(v, where, [&](auto&& node) { a.push_back(std::move(node)); });
}

}  // namespace

toml::table to_toml(const py::dict& d, const std::string& where) {
  toml::table t;
  for (auto [k, v] : d) {
    if (!py::isinstance<py::str>(k)) throw py::type_error(where + ": keys must be strings");
    const std::string key = k.cast<std::string>();
    put_value(v, where + "." + key, [&](auto&& node) { t.insert_or_assign(key, std::move(node)); });
  }
  return t;
}

py::object to_python(const toml::node& n) {
  if (const auto* t = n.as_table()) {
    py::dict d;
    for (const auto& [k, v] : *t) d[py::str(std::string(k.str()))] = to_python(v);
    return std::move(d);
  }
  if (const auto* a = n.as_array()) {
    py::list l;
    for (const auto& v : *a) l.append(to_python(v));
    return std::move(l);
  }
  if (const auto* s = n.as_string()) return py::str(s->get());
  if (const auto* i = n.as_integer()) return py::int_(i->get());
  if (const auto* f = n.as_floating_point()) return py::float_(f->get());
  if (const auto* b = n.as_boolean()) return py::bool_(b->get());
  return py::none();  // dates and times: not used by granflow's files
}

py::array_t<double> to_array(const std::vector<double>& v) {
  py::array_t<double> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::dict columns_dict(const std::vector<std::string>& names, const std::vector<std::vector<double>>& columns) {
  py::dict d;
  for (std::size_t i = 0; i < names.size(); ++i) d[py::str(names[i])] = to_array(columns[i]);
  return d;
}

}  // namespace granflow::python
