// Small text helpers (internal): user data quoted safely and briefly for messages, numbers
// readably, and the one splitter, trimmer and joiner of fields.
#ifndef WALKGRAPH_SRC_UTIL_TEXT_H_
#define WALKGRAPH_SRC_UTIL_TEXT_H_

#include <string>
#include <string_view>
#include <vector>

namespace walkgraph::internal {

// At most this many bytes of one field are echoed in a message.
inline constexpr size_t kMaxEchoBytes = 120;

// 'text' for a message: control bytes and bytes that are not UTF-8 shown as \xNN, cut after
// kMaxEchoBytes with "... (N bytes)".
std::string Quoted(std::string_view text, size_t max_bytes = kMaxEchoBytes);
// Where a number was expected: at most 24 bytes echoed.
inline std::string QuotedNumber(std::string_view text) { return Quoted(text, 24); }

// A number for a message or a table: %g with `significant_digits` (six: plain %g), never
// hundreds of digits.
std::string Num(double value, int significant_digits = 6);
// The shortest decimal text that reads back to the same double (the walk and trajectory files'
// numbers: no digit lost, none added; 0.1 is "0.1", 1e-7 is "1e-07").
std::string ExactNum(double value);
// `value` with `decimals` digits after the point (std::fixed: 0.5 at 2 is "0.50").
std::string Fixed(double value, int decimals);

// The fields of `line` between each `separator`, as they are (empty fields kept: "a,,b" has
// three, "" has one).
std::vector<std::string> Split(std::string_view line, char separator);
// `text` without the spaces and tabs around it.
std::string Trim(std::string_view text);
// `parts` with `separator` between each two.
std::string Join(const std::vector<std::string>& parts, std::string_view separator);

// True when `text` is valid UTF-8 (no overlong forms, no surrogates).
bool IsValidUtf8(std::string_view text);
// `text` with every byte that is not part of valid UTF-8 replaced by '?' (e.g. a walk name made
// from a file name).
std::string ToValidUtf8(std::string_view text);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_TEXT_H_
