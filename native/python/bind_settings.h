// Conversions between Python values and RenderSettings through the one
// settings table (render/setting_table.h).
#pragma once

#include <string>

#include "bindings.h"
#include "render/settings.h"

namespace coherent::python {

// `settings` (a dict or None) overlaid with `kwargs`: every key a table row
// or "border". Raises TypeError for an unknown name or a value of the wrong
// type, ValueError for one out of range, each naming the setting.
RenderSettings settings_from_python(const py::object& settings, const py::kwargs& kwargs);
// Every table row by name (Size as a tuple).
py::dict settings_to_python(const RenderSettings& settings);
// "name: help; accepted (default X)" per row, for the Renderer docstring.
std::string settings_docstring();

void bind_settings(py::module_& m);

}  // namespace coherent::python
