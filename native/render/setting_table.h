// The one table of render settings: every RenderSettings field a front end
// can set, with its name, type, choices, range, default and help, defined
// once. The CLI's options and --help, the Python module's keyword arguments,
// the Blender properties (enum items, ranges, tooltips) and the JSON report's
// settings block are all generated from it, and validate() is the one check
// every front end and the Renderer go through. Adding a setting is one row in
// setting_table.cpp plus its use.
//
// Invariants:
//   - a setting's default is the value RenderSettings{} holds, read through
//     the row's `get` (so the table cannot disagree with the struct);
//   - `set` is only ever called with a value that check_setting_value()
//     accepted, so the struct never holds an out-of-range value that came
//     through the table;
//   - validate() accepts exactly the settings a Renderer can render.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "settings.h"

namespace coherent {

// How a setting's value is spelled in every front end:
//   Bool:   a flag (CLI: --name without a value; Python: bool).
//   Int:    an integer in [min, max], or one of `allowed` when that is set.
//   Seed:   any unsigned 64-bit integer.
//   Real:   a finite number in [min, max].
//   Choice: one of `choices` by name (CLI and Python: lower-case names;
//           Blender: the same names upper-cased as enum identifiers).
//   Size:   a (width, height) pair of integers, each in [min, max]
//           (CLI: WxH; Python: a 2-tuple; Blender: an integer vector).
enum class SettingType : uint8_t { Bool, Int, Seed, Real, Choice, Size };

using SettingSize = std::array<int64_t, 2>;
// A value in front-end-neutral form; the alternative matches the type:
// Bool -> bool, Int -> int64_t, Seed -> uint64_t, Real -> double,
// Choice -> std::string (the choice's name), Size -> SettingSize.
using SettingValue = std::variant<bool, int64_t, uint64_t, double, std::string, SettingSize>;

struct SettingChoice {
    std::string name;   // "pt"
    std::string label;  // "Path Tracing"
    std::string help;
    bool hidden = false;  // an accepted alias that UIs do not list ("wide" = "single")
};

struct SettingSpec {
    std::string name;   // snake_case: the Python keyword and JSON key
    std::string label;  // title in UIs: "Max Bounces"
    // Where a UI shows it: "Sampling", "Light Paths", "Tracing",
    // "Performance", "Film" or "Output".
    std::string group;
    SettingType type = SettingType::Bool;
    double min = 0.0, max = 0.0;  // Int, Real, Size: inclusive hard range
    double soft_max = 0.0;        // end of a UI slider; 0 = max
    std::vector<int64_t> allowed;  // Int: the only values accepted, when not empty
    std::vector<SettingChoice> choices;  // Choice
    std::string help;   // one or two sentences, no trailing period needed by callers
    std::string cli_name;  // "--max-bounces"; derived from name unless the row overrides it
    std::function<SettingValue(const RenderSettings&)> get;
    std::function<void(RenderSettings&, const SettingValue&)> set;

    SettingValue default_value() const { return get(RenderSettings{}); }
};

// A setting that was given a value it cannot take, or settings that cannot
// be rendered together. `setting` names the table row ("" for rules that
// span several, where the message names them); what() is the message
// without the setting's name, so each front end can prefix its own
// spelling ("--max-bounces" or "max_bounces").
class SettingError : public std::invalid_argument {
public:
    SettingError(std::string setting, const std::string& message)
        : std::invalid_argument(message), setting_(std::move(setting)) {}
    const std::string& setting() const { return setting_; }

private:
    std::string setting_;
};

// Every row, in the order front ends list them.
const std::vector<SettingSpec>& setting_table();
// The row named `name` (snake_case), or nullptr.
const SettingSpec* find_setting(std::string_view name);

// Why `value` is not acceptable for `spec` (wrong alternative, out of range,
// unknown choice), or "" when it is.
std::string check_setting_value(const SettingSpec& spec, const SettingValue& value);
// check_setting_value, then set. Throws SettingError naming the row.
void assign_setting(RenderSettings& settings, const SettingSpec& spec, const SettingValue& value);
// Strict parse of the CLI spelling (the whole text must be one value of the
// row's type; Bool accepts true/false/1/0). Throws SettingError.
SettingValue parse_setting_text(const SettingSpec& spec, std::string_view text);
// The value as the CLI spells it (and as help texts show defaults).
std::string format_setting_value(const SettingSpec& spec, const SettingValue& value);
// A one-line description of what the row accepts: "an integer in [0, 1024]",
// "one of pt, drt, wrt, rcs, ao".
std::string describe_accepted(const SettingSpec& spec);

// Largest frame the film may hold, in pixels: ~16K x 16K.
constexpr int64_t kMaxRenderPixels = int64_t(1) << 28;

// Every row's value in range, plus the rules that span rows (frame size,
// render border). Throws SettingError on the first violation. The Renderer
// calls it, so a front end that forgets still gets the error.
void validate(const RenderSettings& settings);

}  // namespace coherent
