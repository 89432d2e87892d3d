#include "program/gcode_lexer.hpp"

#include <cctype>

namespace vmsim::program::gcode {

namespace {

constexpr int kMaxCallArgs = 30;  // #1..#30

struct LineError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string show_byte(char c) {
  if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) {
    static const char* hex = "0123456789abcdef";
    const auto u = static_cast<unsigned char>(c);
    return std::string("byte 0x") + hex[u >> 4] + hex[u & 15];
  }
  return std::string("'") + c + "'";
}

// What `rs274` prints in its N column (print_nc_line_number): the raw line is scanned past blanks and '/';
// an 'N' there is printed with the digits that follow it, otherwise "N.....".
std::string rs274_n_word(std::string_view raw) {
  std::size_t k = 0;
  while (k < raw.size() && (raw[k] == ' ' || raw[k] == '\t' || raw[k] == '/')) ++k;
  if (k < raw.size() && (raw[k] == 'n' || raw[k] == 'N')) {
    std::string s = "N";
    for (++k; k < raw.size() && is_digit(raw[k]); ++k) s += raw[k];
    return s;
  }
  return "N.....";
}

struct OKeyword {
  std::string_view text;
  OKind kind;
};
constexpr OKeyword kOKeywords[] = {
    {"sub", OKind::Sub},
    {"endsub", OKind::EndSub},
    {"return", OKind::Return},
    {"call", OKind::Call},
    {"if", OKind::If},
    {"elseif", OKind::ElseIf},
    {"else", OKind::Else},
    {"endif", OKind::EndIf},
    {"while", OKind::While},
    {"endwhile", OKind::EndWhile},
    {"do", OKind::Do},
    {"repeat", OKind::Repeat},
    {"endrepeat", OKind::EndRepeat},
    {"break", OKind::Break},
    {"continue", OKind::Continue},
};

class LineReader {
 public:
  LineReader(std::string_view text, ExprPool& pool, NameTable& names) : text_(text), pool_(pool), names_(names) {}

  void read(SourceLine& line) {
    if (pos_ < text_.size() && text_[pos_] == '/') {
      line.block_delete = true;
      ++pos_;
    }
    if (pos_ < text_.size() && text_[pos_] == 'n') {
      ++pos_;
      if (!is_digit(peek())) throw LineError("N must be followed by a line number");
      while (is_digit(peek())) ++pos_;
      if (peek() == '.') throw LineError("N line numbers must be whole numbers");
    }
    if (pos_ < text_.size() && text_[pos_] == 'o') {
      line.unreadable_oword = true;  // until it is read
      line.oword = oword();
      line.unreadable_oword = false;
      line.has_content = true;
      return;
    }
    while (pos_ < text_.size()) {
      const char c = text_[pos_];
      if (c == '#') {
        ++pos_;
        line.assignments.push_back(assignment());
      } else if (is_lower(c)) {
        if (c == 'n') throw LineError("an N word is only allowed at the start of a line");
        if (c == 'o') throw LineError("an O-word is only allowed at the start of a line");
        ++pos_;
        const char letter = static_cast<char>(c - 'a' + 'A');
        try {
          line.words.push_back({letter, parser().value()});
        } catch (const ExprError& e) {
          throw LineError(std::string(1, letter) + " word: " + e.what());
        }
      } else {
        throw LineError("unexpected character " + show_byte(c));
      }
    }
    line.has_content = line.has_content || !line.words.empty() || !line.assignments.empty();
  }

 private:
  char peek() const { return pos_ < text_.size() ? text_[pos_] : '\0'; }
  ExprParser parser() { return ExprParser(text_, pos_, pool_, names_); }

  Assignment assignment() {
    Assignment a;
    try {
      if (peek() == '<')
        a.name = parser().named_param_name();
      else
        a.index = parser().value();
    } catch (const ExprError& e) {
      throw LineError(std::string("parameter setting: ") + e.what());
    }
    if (peek() != '=')
      throw LineError("parameter setting needs '=' after the parameter, found " +
                      (peek() ? show_byte(peek()) : std::string("end of line")));
    ++pos_;
    try {
      a.value = parser().value();
    } catch (const ExprError& e) {
      throw LineError(std::string("parameter setting: ") + e.what());
    }
    return a;
  }

  OWord oword() {
    ++pos_;  // 'o'
    OWord o;
    if (peek() == '<') {
      const std::size_t end = text_.find('>', pos_);
      if (end == std::string_view::npos) throw LineError("O-word name has no closing '>'");
      if (end == pos_ + 1) throw LineError("O-word name is empty");
      o.label = std::string(text_.substr(pos_, end + 1 - pos_));
      pos_ = end + 1;
    } else if (is_digit(peek())) {
      std::string digits;
      while (is_digit(peek())) digits += text_[pos_++];
      const std::size_t nz = digits.find_first_not_of('0');
      o.label = nz == std::string::npos ? "0" : digits.substr(nz);
    } else {
      throw LineError("O must be followed by a number or a <name>");
    }
    std::string keyword;
    while (is_lower(peek())) keyword += text_[pos_++];
    bool found = false;
    for (const OKeyword& k : kOKeywords) {
      if (keyword == k.text) {
        o.kind = k.kind;
        found = true;
        break;
      }
    }
    const std::string name = oword_name(o.label);
    if (!found) {
      if (keyword.empty()) throw LineError(name + " needs a keyword (sub, call, if, while, ...)");
      throw LineError(name + ": unknown O-word keyword \"" + keyword + "\"");
    }
    try {
      switch (o.kind) {
        case OKind::Call:
          while (peek() == '[') {
            if (o.args.size() == kMaxCallArgs)
              throw LineError(name + " call: more than " + std::to_string(kMaxCallArgs) + " arguments");
            o.args.push_back(parser().value());
          }
          break;
        case OKind::If:
        case OKind::ElseIf:
        case OKind::While:
        case OKind::Repeat:
          if (peek() != '[')
            throw LineError(name + " " + keyword + " needs a bracketed expression, e.g. " + name + " " + keyword +
                            " [#1 LT 3]");
          o.expr = parser().value();
          break;
        case OKind::Return:
        case OKind::EndSub:
          if (peek() == '[') o.expr = parser().value();
          break;
        default:
          break;
      }
    } catch (const ExprError& e) {
      throw LineError(name + " " + keyword + ": " + e.what());
    }
    if (pos_ < text_.size())
      throw LineError(name + " " + keyword + ": unexpected " + show_byte(peek()) +
                      " (an O-word line holds only the O-word and comments)");
    return o;
  }

  std::string_view text_;
  std::size_t pos_ = 0;
  ExprPool& pool_;
  NameTable& names_;
};

void read_line(std::string_view raw, SourceLine& line, ExprPool& pool, NameTable& names) {
  line.n_word = rs274_n_word(raw);
  // Normalise as LinuxCNC does: comments out, blanks out, letters lowered.
  std::string text;
  text.reserve(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const char c = raw[i];
    if (c == '(') {
      std::size_t j = i + 1;
      for (; j < raw.size() && raw[j] != ')'; ++j)
        if (raw[j] == '(') throw LineError("nested comment: '(' inside a ( ) comment");
      if (j == raw.size()) throw LineError("comment is not closed: '(' without ')'");
      line.comment = std::string(raw.substr(i + 1, j - i - 1));
      line.has_content = true;
      i = j;
      continue;
    }
    if (c == ';') break;
    if (c == ' ' || c == '\t' || c == '\r') continue;
    text += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  if (text == "%") {
    line.percent = true;
    return;
  }
  LineReader(text, pool, names).read(line);
}

// (debug,...) and friends may name parameters the code never mentions; intern them too, so that they can be
// looked up like any other name.
void intern_comment_names(const std::string& comment, NameTable& names) {
  for (std::size_t i = comment.find("#<"); i != std::string::npos; i = comment.find("#<", i + 2)) {
    const std::size_t close = comment.find('>', i + 2);
    if (close == std::string::npos) return;
    std::string name;
    for (std::size_t k = i + 2; k < close; ++k)
      if (!std::isspace(static_cast<unsigned char>(comment[k])))
        name += static_cast<char>(std::tolower(static_cast<unsigned char>(comment[k])));
    if (!name.empty()) names.intern(name);
  }
}

}  // namespace

std::string oword_name(const std::string& label) {
  std::string s = "o";
  s += label;
  return s;
}

const char* oword_keyword(OKind kind) {
  for (const OKeyword& k : kOKeywords)
    if (k.kind == kind) return k.text.data();
  return "?";
}

ParsedProgram parse_program(std::string_view text) {
  ParsedProgram program;
  // Set by every subroutine return, whether or not the program reads them.
  program.names.intern("_value");
  program.names.intern("_value_returned");
  std::size_t start = 0;
  int number = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string_view raw = text.substr(start, end - start);
    if (!raw.empty() && raw.back() == '\r') raw.remove_suffix(1);
    SourceLine& line = program.lines.emplace_back();
    line.number = ++number;
    try {
      read_line(raw, line, program.exprs, program.names);
      if (line.comment) intern_comment_names(*line.comment, program.names);
    } catch (const LineError& e) {
      // Keep the line (its N word, its number) but nothing to execute: the error is raised if it runs.
      line.error = e.what();
      line.words.clear();
      line.assignments.clear();
      line.oword.reset();
      line.comment.reset();
      line.percent = false;
      line.has_content = true;
    }
    start = end + 1;
  }
  return program;
}

}  // namespace vmsim::program::gcode
