// Text for configuration error messages: how a TOML value, a number bound or a type is spelled
// when we tell the user what was wrong. Kept apart from the schema reader so every loader words
// values the same way ("1000.0" for a float, "\"fast\"" for a string, "nan" for NaN).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include <toml++/toml.h>

namespace trainer::config::detail {

inline constexpr std::int64_t kNanosecondsPerMicrosecond = 1000;

// A number as a bound or a computed quantity: integral values without a fraction ("100000",
// not "1e+05"), others in the shortest form that reads back exactly.
std::string format_number(double value);

// A computed quantity to 3 significant digits ("-0.0995"), for diagnostics where the exact
// digits do not matter.
std::string format_significant(double value);

// A TOML value as it would appear in the file: floats always with a fraction or exponent
// ("1000.0"), strings quoted, arrays shortened after a few elements, tables as "{...}".
std::string format_value(const toml::node& node);

// "integer", "float", "string", "boolean", "array", "table", "date", "time", "date-time".
std::string_view type_name(const toml::node& node) noexcept;

// A string quoted and escaped as a TOML basic string.
std::string quote(std::string_view text);

}  // namespace trainer::config::detail
