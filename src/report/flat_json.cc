#include "ltlo/report/flat_json.h"

#include <cctype>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "ltlo/core/errors.h"

namespace ltlo::report {
namespace {

class Parser {
 public:
  Parser(const std::string& text, const std::string& source) : text_(text), source_(source) {}

  [[noreturn]] void fail(const std::string& what) const {
    int line = 1;
    for (std::size_t i = 0; i < pos_ && i < text_.size(); ++i) line += text_[i] == '\n';
    throw InputError(source_, line, what);
  }
  void skipSpace() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool consume(char c) {
    skipSpace();
    if (pos_ < text_.size() && text_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  void expect(char c) {
    if (!consume(c)) fail(std::string("expected '") + c + "'");
  }
  std::string string() {
    skipSpace();
    if (pos_ >= text_.size() || text_[pos_] != '"') fail("expected a string");
    ++pos_;
    std::string out;
    while (pos_ < text_.size() && text_[pos_] != '"') {
      char c = text_[pos_++];
      if (c == '\\' && pos_ < text_.size()) {
        const char e = text_[pos_++];
        c = e == 'n' ? '\n' : e == 't' ? '\t' : e;
      }
      out.push_back(c);
    }
    if (pos_ >= text_.size()) fail("unterminated string");
    ++pos_;
    return out;
  }
  bool word(const char* w) {
    skipSpace();
    const std::size_t n = std::char_traits<char>::length(w);
    if (text_.compare(pos_, n, w) == 0) {
      pos_ += n;
      return true;
    }
    return false;
  }
  double number() {
    skipSpace();
    const char* begin = text_.c_str() + pos_;
    char* end = nullptr;
    const double value = std::strtod(begin, &end);
    if (end == begin) fail("expected a value (number, string, true, false or null)");
    pos_ += static_cast<std::size_t>(end - begin);
    return value;
  }
  bool atEnd() {
    skipSpace();
    return pos_ >= text_.size();
  }
  char peek() {
    skipSpace();
    return pos_ < text_.size() ? text_[pos_] : '\0';
  }

 private:
  const std::string& text_;
  const std::string& source_;
  std::size_t pos_ = 0;
};

}  // namespace

FlatJson FlatJson::read(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open JSON file");
  std::ostringstream os;
  os << in.rdbuf();
  return parse(os.str(), path);
}

FlatJson FlatJson::parse(const std::string& text, const std::string& source) {
  FlatJson json;
  Parser p(text, source);
  p.expect('{');
  if (!p.consume('}')) {
    do {
      const std::string key = p.string();
      p.expect(':');
      const char c = p.peek();
      if (c == '"') {
        json.texts_[key] = p.string();
      } else if (c == '{' || c == '[') {
        p.fail("nested value under \"" + key + "\" (a flat object is expected)");
      } else if (p.word("true")) {
        json.numbers_[key] = 1.0;
      } else if (p.word("false")) {
        json.numbers_[key] = 0.0;
      } else if (!p.word("null")) {
        json.numbers_[key] = p.number();
      }
    } while (p.consume(','));
    p.expect('}');
  }
  if (!p.atEnd()) p.fail("text after the closing '}'");
  return json;
}

std::optional<double> FlatJson::number(const std::string& key) const {
  auto it = numbers_.find(key);
  if (it == numbers_.end()) return std::nullopt;
  return it->second;
}

std::optional<std::string> FlatJson::text(const std::string& key) const {
  auto it = texts_.find(key);
  if (it == texts_.end()) return std::nullopt;
  return it->second;
}

}  // namespace ltlo::report
