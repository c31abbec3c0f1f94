// Python side of the settings table (render/setting_table.h): turning
// keyword arguments into RenderSettings with the table's one validation,
// RenderSettings back into a dict, and `settings_table()`, from which the
// Blender add-on builds its properties at registration.
#include "bind_settings.h"

#include <cstdint>

#include "render/setting_table.h"

namespace coherent::python {
namespace {

const char* type_name(SettingType t) {
    switch (t) {
        case SettingType::Bool: return "bool";
        case SettingType::Int: return "int";
        case SettingType::Seed: return "seed";
        case SettingType::Real: return "real";
        case SettingType::Choice: return "choice";
        case SettingType::Size: return "size";
    }
    return "?";
}

[[noreturn]] void wrong_type(const SettingSpec& spec, const py::handle& obj) {
    throw py::type_error(spec.name + ": expected " + describe_accepted(spec) + ", got " +
                         std::string(py::str(py::type::of(obj).attr("__name__"))) + " " +
                         std::string(py::repr(obj)));
}

int64_t to_int64(const SettingSpec& spec, const py::handle& obj) {
    if (!is_python_integer(obj)) wrong_type(spec, obj);
    const py::int_ i = py::reinterpret_steal<py::int_>(PyNumber_Index(obj.ptr()));
    int overflow = 0;
    const long long v = PyLong_AsLongLongAndOverflow(i.ptr(), &overflow);
    if (overflow) throw py::value_error(spec.name + ": expected " + describe_accepted(spec) + ", got " +
                                        std::string(py::repr(obj)));
    return int64_t(v);
}

SettingValue to_value(const SettingSpec& spec, const py::handle& obj) {
    switch (spec.type) {
        case SettingType::Bool:
            if (!PyBool_Check(obj.ptr())) wrong_type(spec, obj);
            return obj.cast<bool>();
        case SettingType::Int: return to_int64(spec, obj);
        case SettingType::Seed: {
            if (!is_python_integer(obj)) wrong_type(spec, obj);
            const py::int_ i = py::reinterpret_steal<py::int_>(PyNumber_Index(obj.ptr()));
            const unsigned long long v = PyLong_AsUnsignedLongLong(i.ptr());
            if (PyErr_Occurred()) {
                PyErr_Clear();
                throw py::value_error(spec.name + ": expected " + describe_accepted(spec) + ", got " +
                                      std::string(py::repr(obj)));
            }
            return uint64_t(v);
        }
        case SettingType::Real:
            if (!is_python_number(obj)) wrong_type(spec, obj);
            return py::float_(py::reinterpret_borrow<py::object>(obj)).cast<double>();
        case SettingType::Choice:
            if (!py::isinstance<py::str>(obj)) wrong_type(spec, obj);
            return obj.cast<std::string>();
        case SettingType::Size: {
            if (!py::isinstance<py::sequence>(obj) || py::isinstance<py::str>(obj)) wrong_type(spec, obj);
            if (py::len(obj) != 2)
                throw py::value_error(spec.name + ": expected " + describe_accepted(spec) + " as a pair, got " +
                                      std::string(py::repr(obj)));
            const py::sequence seq = py::reinterpret_borrow<py::sequence>(obj);
            return SettingSize{to_int64(spec, seq[0]), to_int64(spec, seq[1])};
        }
    }
    wrong_type(spec, obj);
}

py::object to_python(const SettingValue& value) {
    return std::visit(
        [](const auto& v) -> py::object {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, SettingSize>) return py::make_tuple(v[0], v[1]);
            else return py::cast(v);
        },
        value);
}

// border=(x0, y0, x1, y1) in pixels, y = 0 at the top: the frame region the
// film covers. Not a table row: it is the frame's geometry, which Blender
// derives from its own border settings; validate() checks it.
void set_border(RenderSettings& s, const py::handle& border) {
    if (border.is_none()) return;
    if (!py::isinstance<py::sequence>(border) || py::isinstance<py::str>(border))
        throw py::type_error("border: expected (x0, y0, x1, y1) in pixels or None");
    if (py::len(border) != 4)
        throw py::value_error("border: expected 4 corners (x0, y0, x1, y1), got " + std::string(py::repr(border)));
    const py::sequence b = py::reinterpret_borrow<py::sequence>(border);
    int* corners[4] = {&s.border_x0, &s.border_y0, &s.border_x1, &s.border_y1};
    for (size_t i = 0; i < 4; ++i) {
        const long long v = integer_arg(b[i], "border");
        if (v < 0 || v > (1 << 16)) throw py::value_error("border: corner " + std::to_string(v) + " is outside any frame");
        *corners[i] = int(v);
    }
}

py::dict spec_dict(const SettingSpec& spec) {
    py::dict d;
    d["name"] = spec.name;
    d["label"] = spec.label;
    d["group"] = spec.group;
    d["type"] = type_name(spec.type);
    d["min"] = spec.min;
    d["max"] = spec.max;
    d["soft_max"] = spec.soft_max > 0.0 ? spec.soft_max : spec.max;
    d["allowed"] = spec.allowed;
    py::list choices;
    for (const SettingChoice& c : spec.choices) choices.append(py::make_tuple(c.name, c.label, c.help, c.hidden));
    d["choices"] = choices;
    d["help"] = spec.help;
    d["accepted"] = describe_accepted(spec);
    d["cli_name"] = spec.cli_name;
    d["default"] = to_python(spec.default_value());
    return d;
}

}  // namespace

RenderSettings settings_from_python(const py::object& settings, const py::kwargs& kwargs) {
    py::dict all;
    if (!settings.is_none()) {
        if (!py::isinstance<py::dict>(settings)) throw py::type_error("settings: expected a dict or None");
        for (auto item : py::reinterpret_borrow<py::dict>(settings)) all[item.first] = item.second;
    }
    for (auto item : kwargs) all[item.first] = item.second;  // keywords win over the dict

    RenderSettings s;
    for (auto item : all) {
        const std::string name = py::str(item.first);
        if (name == "border") {
            set_border(s, item.second);
            continue;
        }
        const SettingSpec* spec = find_setting(name);
        if (!spec) throw py::type_error("unknown setting '" + name + "' (coherent.settings_table() lists them)");
        const SettingValue v = to_value(*spec, item.second);
        if (std::string why = check_setting_value(*spec, v); !why.empty()) throw py::value_error(name + ": " + why);
        spec->set(s, v);
    }
    try {
        validate(s);
    } catch (const SettingError& e) {
        throw py::value_error((e.setting().empty() ? "" : e.setting() + ": ") + e.what());
    }
    return s;
}

py::dict settings_to_python(const RenderSettings& s) {
    py::dict d;
    for (const SettingSpec& spec : setting_table()) d[py::str(spec.name)] = to_python(spec.get(s));
    return d;
}

std::string settings_docstring() {
    std::string doc;
    for (const SettingSpec& spec : setting_table()) {
        doc += spec.name + ": " + spec.help + "; " + describe_accepted(spec) + " (default " +
               format_setting_value(spec, spec.default_value()) + ")\n";
    }
    return doc;
}

void bind_settings(py::module_& m) {
    m.def(
        "settings_table",
        [] {
            py::list rows;
            for (const SettingSpec& spec : setting_table()) rows.append(spec_dict(spec));
            return rows;
        },
        R"doc(
The render settings table: one dict per setting with name, label, group,
type ('bool', 'int', 'seed', 'real', 'choice', 'size'), min, max, soft_max,
allowed (int values, when restricted), choices [(name, label, help, hidden)],
help, accepted (what values are accepted, in words), cli_name and default.
Renderer(...) takes exactly these names as keywords (plus border); the
Blender add-on builds its properties from it.)doc");
}

}  // namespace coherent::python
