#include "mobmap/util/field_error.hpp"

#include <cctype>

namespace mobmap::util {

std::string fieldName(std::string_view name) { return "`" + std::string(name) + "`"; }

std::string respellFields(std::string_view message, const FieldSpelling& spelling) {
  const auto isNameChar = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; };
  std::string out;
  out.reserve(message.size());
  std::size_t i = 0;
  while (i < message.size()) {
    if (message[i] == '`') {
      std::size_t end = i + 1;
      while (end < message.size() && isNameChar(message[end])) ++end;
      if (end > i + 1 && end < message.size() && message[end] == '`') {
        const std::string_view name = message.substr(i + 1, end - i - 1);
        if (const std::optional<std::string> spelled = spelling(name)) {
          out += *spelled;
          i = end + 1;
          continue;
        }
        out.append(message.substr(i, end + 1 - i));
        i = end + 1;
        continue;
      }
    }
    out += message[i++];
  }
  return out;
}

}  // namespace mobmap::util
