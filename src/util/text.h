// Text for messages (internal): user data quoted safely and briefly, numbers readably.
#ifndef WALKGRAPH_SRC_UTIL_TEXT_H_
#define WALKGRAPH_SRC_UTIL_TEXT_H_

#include <string>
#include <string_view>

namespace walkgraph::internal {

// At most this many bytes of one field are echoed in a message.
inline constexpr size_t kMaxEchoBytes = 120;

// 'text' for a message: control bytes and bytes that are not UTF-8 shown as \xNN, cut after
// kMaxEchoBytes with "... (N bytes)".
std::string Quoted(std::string_view text, size_t max_bytes = kMaxEchoBytes);
// Where a number was expected: at most 24 bytes echoed.
inline std::string QuotedNumber(std::string_view text) { return Quoted(text, 24); }

// A number for a message: %g (six significant digits), never hundreds of digits.
std::string Num(double value);

// True when `text` is valid UTF-8 (no overlong forms, no surrogates).
bool IsValidUtf8(std::string_view text);
// `text` with every byte that is not part of valid UTF-8 replaced by '?' (e.g. a walk name made
// from a file name).
std::string ToValidUtf8(std::string_view text);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_TEXT_H_
