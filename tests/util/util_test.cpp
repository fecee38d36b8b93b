// The shared utilities: respelling the fields library messages name, and the bounds on
// JSON read from outside.
#include "mobmap/util/field_error.hpp"
#include "mobmap/util/json_limits.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <functional>
#include <map>
#include <random>
#include <string>
#include <vector>

namespace mobmap::util {
namespace {

using Json = nlohmann::json;

TEST(FieldError, NamesTheFieldInBackquotesAndKeepsItsParts) {
  const FieldError e("max_pose_gap_s", "must be >= 0, got -1");
  EXPECT_STREQ(e.what(), "`max_pose_gap_s` must be >= 0, got -1");
  EXPECT_EQ(e.field(), "max_pose_gap_s");
  EXPECT_EQ(e.problem(), "must be >= 0, got -1");
}

// Every name a spelling knows is replaced, the others keep their backquotes, and text
// that only looks like a name (an empty pair, a space inside, an unclosed quote) is left.
TEST(FieldError, RespellReplacesExactlyTheNamesTheFrontKnows) {
  const std::map<std::string, std::string, std::less<>> flags{{"max_step_m", "--max-step"}, {"depth_topic", "--depth-topic"}};
  const FieldSpelling cli = [&](std::string_view name) -> std::optional<std::string> {
    const auto it = flags.find(name);
    return it == flags.end() ? std::nullopt : std::optional<std::string>(it->second);
  };
  EXPECT_EQ(respellFields("over `max_step_m` 0.2 (`weight`)", cli), "over --max-step 0.2 (`weight`)");
  EXPECT_EQ(respellFields("`depth_topic``max_step_m`", cli), "--depth-topic--max-step");
  EXPECT_EQ(respellFields("`` `a b` `max_step_m", cli), "`` `a b` `max_step_m");
  EXPECT_EQ(respellFields("", cli), "");
  // Against a brute force: random text of letters, backquotes and spaces, respelled with
  // every name marked, equals a character-by-character scan written the plain way.
  std::mt19937 rng(3);
  const std::string alphabet = "ab_`` ";
  const FieldSpelling upper = [](std::string_view name) -> std::optional<std::string> {
    if (name.size() % 2) return std::nullopt;
    return "<" + std::string(name) + ">";
  };
  for (int trial = 0; trial < 2000; ++trial) {
    std::string text;
    for (int i = 0, n = static_cast<int>(rng() % 12); i < n; ++i) text += alphabet[rng() % alphabet.size()];
    std::string expected;
    for (std::size_t i = 0; i < text.size();) {
      std::size_t close = text.find('`', i + 1);
      const bool marked = text[i] == '`' && close != std::string::npos && close > i + 1 &&
                          text.find_first_not_of("ab_", i + 1) == close;
      if (marked) {
        const std::string name = text.substr(i + 1, close - i - 1);
        expected += upper(name).value_or("`" + name + "`");
        i = close + 1;
      } else {
        expected += text[i++];
      }
    }
    EXPECT_EQ(respellFields(text, upper), expected) << text;
  }
}

// checkJsonLimits against the parsed document: depth and value counts of random JSON
// (brackets, quotes and backslashes inside strings among them) equal what a walk of the
// parsed value finds, and each limit is refused exactly past its number.
TEST(JsonLimits, DepthAndValuesAreThoseOfTheParsedDocument) {
  std::mt19937 rng(7);
  const std::vector<std::string> strings{"\"a\"", "\"[{\"", "\"\\\"]\"", "\"\\\\\"", "\"}}}\""};
  // A random value of at most `depth` levels; its depth and count by construction.
  std::function<std::string(int, std::size_t&, std::size_t&)> value = [&](int depth, std::size_t& deepest,
                                                                           std::size_t& count) -> std::string {
    ++count;
    const int kind = depth == 0 ? static_cast<int>(rng() % 3) : static_cast<int>(rng() % 5);
    if (kind == 0) return std::to_string(static_cast<int>(rng() % 2000) - 1000);
    if (kind == 1) return strings[rng() % strings.size()];
    if (kind == 2) return rng() % 2 ? "true" : "null";
    std::size_t inner = 0;
    std::string out = kind == 3 ? "[" : "{";
    const int n = static_cast<int>(rng() % 4);
    for (int i = 0; i < n; ++i) {
      std::size_t d = 0;
      if (i) out += ",";
      if (kind == 4) {
        out += strings[rng() % strings.size()] + ":";
        ++count;  // a key is a string too
      }
      out += value(depth - 1, d, count);
      inner = std::max(inner, d);
    }
    deepest = inner + 1;
    return out + (kind == 3 ? "]" : "}");
  };
  for (int trial = 0; trial < 300; ++trial) {
    std::size_t depth = 0, count = 0;
    const std::string text = value(static_cast<int>(rng() % 8), depth, count);
    Json parsed;
    ASSERT_NO_THROW(parsed = Json::parse(text)) << text;  // valid JSON, as generated
    EXPECT_FALSE(checkJsonLimits(text, {depth, count})) << text;
    if (depth > 0) {
      const JsonLimitProblem deep = checkJsonLimits(text, {depth - 1, count});
      EXPECT_EQ(deep.kind, JsonLimitProblem::Kind::kTooDeep) << text;
    }
    EXPECT_EQ(checkJsonLimits(text, {depth, count - 1}).kind, JsonLimitProblem::Kind::kTooManyValues) << text;
  }
  EXPECT_EQ(checkJsonLimits(std::string("{}\0{}", 5)).kind, JsonLimitProblem::Kind::kNulByte);
  EXPECT_FALSE(checkJsonLimits("\"a\\u0000b\""));  // an escaped NUL inside a string is text
}

}  // namespace
}  // namespace mobmap::util
