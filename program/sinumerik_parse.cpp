#include "program/sinumerik_parse.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <stdexcept>

namespace vmsim::program::sinumerik {

namespace {

using gcode::BinaryOp;
using gcode::ExprNode;
using gcode::ExprOp;
using gcode::UnaryFn;

struct LineError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_upper(char c) { return c >= 'A' && c <= 'Z'; }
bool is_ident_start(char c) { return is_upper(c) || c == '_' || c == '$'; }
bool is_ident(char c) { return is_ident_start(c) || is_digit(c); }
char upper(char c) { return c >= 'a' && c <= 'z' ? static_cast<char>(c - 'a' + 'A') : c; }

std::string trim(std::string_view s) {
  std::size_t a = 0, b = s.size();
  while (a < b && (s[a] == ' ' || s[a] == '\t' || s[a] == '\r')) ++a;
  while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\t' || s[b - 1] == '\r')) --b;
  return std::string(s.substr(a, b - a));
}

std::string show(char c) {
  if (c == '\0') return "the end of the line";
  if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) return "a non-printable character";
  return std::string("'") + c + "'";
}

// Commands without operands that the reader knows (the executor gives each its meaning).
constexpr std::array<std::string_view, 31> kKeywords = {
    "TRAORI", "TRAFOOF", "SUPA",     "SOFT",     "BRISK",     "DRIVE",       "FFWON",    "FFWOF",
    "COMPOF", "COMPON",  "COMPCURV", "COMPCAD",  "FNORM",     "UPATH",       "SPATH",    "CFC",
    "CFTCP",  "CFIN",    "STOPRE",   "ORIWKS",   "ORIMKS",    "ORIAXES",     "ORIVECT",  "RET",
    "SPOS",   "WAITM",   "WAITS",    "STOPFIFO", "STARTFIFO", "GROUP_BEGIN", "GROUP_END"};

// Expression parser over the (uppercased) line. Siemens' operator priority, highest first (NC programming, Work
// preparation, "Priority of the operations"): NOT; * / DIV MOD; + -; AND; XOR; OR; the comparisons == <> < > <= >=.
// The 840D compares REAL values exactly, so == <> <= >= are built from < and >, not from the G-code evaluator's
// tolerant EQ/NE/LE/GE (LinuxCNC's 1e-4).
class ExprReader {
 public:
  ExprReader(std::string_view text, std::size_t& pos, gcode::ExprPool& pool, gcode::NameTable& names)
      : text_(text), pos_(pos), pool_(pool), names_(names) {}

  ExprId expression() { return comparison(); }

  // A numeric constant with an optional sign ("-14.543", "90.", ".02", "1.5EX3").
  double constant() {
    const std::size_t start = pos_;
    bool negative = false;
    if (peek() == '+' || peek() == '-') negative = text_[pos_++] == '-';
    std::string digits;
    std::size_t n = 0;
    while (is_digit(peek())) digits += text_[pos_++], ++n;
    if (peek() == '.') {
      digits += text_[pos_++];
      while (is_digit(peek())) digits += text_[pos_++], ++n;
    }
    if (n == 0) {
      pos_ = start;
      throw LineError("expected a number but found " + show(peek()));
    }
    if (peek() == 'E' && peek(1) == 'X') {  // 840D exponent: 1.5EX3
      pos_ += 2;
      digits += 'e';
      if (peek() == '+' || peek() == '-') digits += text_[pos_++];
      std::size_t ne = 0;
      while (is_digit(peek())) digits += text_[pos_++], ++ne;
      if (ne == 0) throw LineError("an exponent EX needs digits");
    }
    if (digits.front() == '.') digits.insert(digits.begin(), '0');
    if (digits.back() == '.') digits.push_back('0');
    double v = 0.0;
    const auto res = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (res.ec != std::errc() || !std::isfinite(v))
      throw LineError("number " + std::string(text_.substr(start, pos_ - start)) + " is out of range");
    return negative ? -v : v;
  }

  ExprId number_node(double v) { return make({.op = ExprOp::Number, .number = v}); }

  void skip_blanks() {
    while (peek() == ' ' || peek() == '\t') ++pos_;
  }
  char peek(std::size_t ahead = 0) const { return pos_ + ahead < text_.size() ? text_[pos_ + ahead] : '\0'; }

 private:
  ExprId make(ExprNode node) {
    int h = 0;
    if (node.lhs != kNoExpr) h = std::max<int>(h, pool_[node.lhs].height);
    if (node.rhs != kNoExpr) h = std::max<int>(h, pool_[node.rhs].height);
    if (h + 1 > gcode::kMaxTreeHeight) throw LineError("expression too deeply nested");
    node.height = static_cast<std::int16_t>(h + 1);
    return pool_.add(node);
  }
  ExprId binary(BinaryOp op, ExprId l, ExprId r) {
    return make({.op = ExprOp::Binary, .fn = static_cast<std::uint8_t>(op), .lhs = l, .rhs = r});
  }
  ExprId unary(UnaryFn fn, ExprId a) {
    return make({.op = ExprOp::Unary, .fn = static_cast<std::uint8_t>(fn), .lhs = a});
  }
  ExprId logical_not(ExprId a) { return binary(BinaryOp::Eq, a, number_node(0.0)); }

  // A word operator (AND, DIV, ...) at pos_ followed by something that cannot continue an identifier.
  bool word_op(std::string_view w) {
    skip_blanks();
    if (text_.substr(pos_, w.size()) != w || is_ident(peek(w.size()))) return false;
    pos_ += w.size();
    return true;
  }

  ExprId comparison() {
    ExprId l = logical_or();
    for (;;) {
      skip_blanks();
      const char c = peek(), d = peek(1);
      if (c == '=' && d == '=') {
        pos_ += 2;
        const ExprId r = logical_or();
        l = logical_not(binary(BinaryOp::Or, binary(BinaryOp::Lt, l, r), binary(BinaryOp::Gt, l, r)));
      } else if (c == '<' && d == '>') {
        pos_ += 2;
        const ExprId r = logical_or();
        l = binary(BinaryOp::Or, binary(BinaryOp::Lt, l, r), binary(BinaryOp::Gt, l, r));
      } else if (c == '<' && d == '=') {
        pos_ += 2;
        l = logical_not(binary(BinaryOp::Gt, l, logical_or()));
      } else if (c == '>' && d == '=') {
        pos_ += 2;
        l = logical_not(binary(BinaryOp::Lt, l, logical_or()));
      } else if (c == '<') {
        ++pos_;
        l = binary(BinaryOp::Lt, l, logical_or());
      } else if (c == '>') {
        ++pos_;
        l = binary(BinaryOp::Gt, l, logical_or());
      } else {
        return l;
      }
    }
  }
  ExprId logical_or() {
    ExprId l = logical_xor();
    while (word_op("OR")) l = binary(BinaryOp::Or, l, logical_xor());
    return l;
  }
  ExprId logical_xor() {
    ExprId l = logical_and();
    while (word_op("XOR")) l = binary(BinaryOp::Xor, l, logical_and());
    return l;
  }
  ExprId logical_and() {
    ExprId l = additive();
    for (;;) {
      if (word_op("AND")) {
        l = binary(BinaryOp::And, l, additive());
      } else if (word_op("B_AND") || word_op("B_OR") || word_op("B_XOR")) {
        throw LineError("the bit operators B_AND, B_OR, B_XOR are not supported");
      } else {
        return l;
      }
    }
  }
  ExprId additive() {
    ExprId l = multiplicative();
    for (;;) {
      skip_blanks();
      if (peek() == '+') {
        ++pos_;
        l = binary(BinaryOp::Plus, l, multiplicative());
      } else if (peek() == '-') {
        ++pos_;
        l = binary(BinaryOp::Minus, l, multiplicative());
      } else {
        return l;
      }
    }
  }
  ExprId multiplicative() {
    ExprId l = prefix();
    for (;;) {
      skip_blanks();
      if (peek() == '*') {
        ++pos_;
        l = binary(BinaryOp::Times, l, prefix());
      } else if (peek() == '/') {
        ++pos_;
        l = binary(BinaryOp::Divide, l, prefix());
      } else if (word_op("DIV")) {  // integer division, truncating
        l = unary(UnaryFn::Trunc, binary(BinaryOp::Divide, l, prefix()));
      } else if (word_op("MOD")) {
        l = binary(BinaryOp::Modulo, l, prefix());
      } else {
        return l;
      }
    }
  }
  ExprId prefix() {
    if (++depth_ > gcode::kMaxBracketDepth) throw LineError("expression nested too deeply");
    struct Depth {
      int& d;
      ~Depth() { --d; }
    } guard{depth_};
    skip_blanks();
    if (peek() == '-') {
      ++pos_;
      return make({.op = ExprOp::Negate, .lhs = prefix()});
    }
    if (peek() == '+') {
      ++pos_;
      return prefix();
    }
    if (word_op("NOT")) return logical_not(prefix());
    return primary();
  }
  ExprId primary() {
    skip_blanks();
    const char c = peek();
    if (c == '(') {
      ++pos_;
      const ExprId e = expression();
      skip_blanks();
      if (peek() != ')') throw LineError("expected ')' but found " + show(peek()));
      ++pos_;
      return e;
    }
    if (is_digit(c) || c == '.') return number_node(constant());
    if (c == '"') throw LineError("a string cannot be used in a numeric expression");
    if (!is_ident_start(c)) throw LineError("expected a value but found " + show(c));
    std::string name;
    while (is_ident(peek())) name += text_[pos_++];
    if (name.front() == '$') throw LineError("system variable " + name + " is not supported");
    if (name.size() >= 2 && name[0] == 'R' && std::all_of(name.begin() + 1, name.end(), is_digit))
      return make({.op = ExprOp::Param, .lhs = number_node(std::stod(name.substr(1)))});
    if (name == "TRUE") return number_node(1.0);
    if (name == "FALSE") return number_node(0.0);
    skip_blanks();
    if (peek() == '(') return function(name);
    return make({.op = ExprOp::NamedParam, .name = names_.intern(name)});
  }
  std::vector<ExprId> arguments(const std::string& name) {
    ++pos_;  // '('
    std::vector<ExprId> args;
    skip_blanks();
    if (peek() == ')') {
      ++pos_;
      return args;
    }
    for (;;) {
      args.push_back(expression());
      skip_blanks();
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() == ')') {
        ++pos_;
        return args;
      }
      throw LineError(name + ": expected ',' or ')' but found " + show(peek()));
    }
  }
  ExprId function(const std::string& name) {
    struct Fn {
      std::string_view name;
      UnaryFn fn;
    };
    static constexpr Fn kFns[] = {
        {"SIN", UnaryFn::Sin},     {"COS", UnaryFn::Cos},     {"TAN", UnaryFn::Tan}, {"ASIN", UnaryFn::Asin},
        {"ACOS", UnaryFn::Acos},   {"SQRT", UnaryFn::Sqrt},   {"ABS", UnaryFn::Abs}, {"TRUNC", UnaryFn::Trunc},
        {"ROUND", UnaryFn::Round}, {"ROUNDUP", UnaryFn::Fup}, {"LN", UnaryFn::Ln},   {"EXP", UnaryFn::Exp},
    };
    const std::vector<ExprId> args = arguments(name);
    auto need = [&](std::size_t n) {
      if (args.size() != n)
        throw LineError(name + " takes " + std::to_string(n) + " argument" + (n == 1 ? "" : "s") + ", not " +
                        std::to_string(args.size()));
    };
    for (const Fn& f : kFns) {
      if (name == f.name) {
        need(1);
        return unary(f.fn, args[0]);
      }
    }
    if (name == "POT") {
      need(1);
      return binary(BinaryOp::Times, args[0], args[0]);
    }
    if (name == "ATAN2") {
      need(2);
      return make({.op = ExprOp::Atan2, .lhs = args[0], .rhs = args[1]});
    }
    if (name == "MINVAL" || name == "MAXVAL") {  // (a + b -/+ |a - b|) / 2
      need(2);
      const ExprId sum = binary(BinaryOp::Plus, args[0], args[1]);
      const ExprId dist = unary(UnaryFn::Abs, binary(BinaryOp::Minus, args[0], args[1]));
      return binary(BinaryOp::Divide, binary(name == "MINVAL" ? BinaryOp::Minus : BinaryOp::Plus, sum, dist),
                    number_node(2.0));
    }
    throw LineError("unknown function " + name + "()");
  }

  std::string_view text_;
  std::size_t& pos_;
  gcode::ExprPool& pool_;
  gcode::NameTable& names_;
  int depth_ = 0;
};

class LineReader {
 public:
  LineReader(std::string_view text, Block& block, Program& program)
      : text_(text), block_(block), program_(program), expr_(text_, pos_, program.exprs, program.names) {}

  void read() {
    skip();
    if (peek() == '/') {
      block_.skip = true;
      ++pos_;
      if (is_digit(peek())) ++pos_;  // skip level /0 .. /9
      skip();
    }
    if (peek() == 'N' && is_digit(peek(1))) {
      std::string n = "N";
      for (++pos_; is_digit(peek()); ++pos_) n += text_[pos_];
      block_.n_word = n;
      skip();
    } else if (peek() == ':' && is_digit(peek(1))) {  // main block number ":10"
      std::string n = ":";
      for (++pos_; is_digit(peek()); ++pos_) n += text_[pos_];
      block_.n_word = n;
      skip();
    }
    read_label();
    while (true) {
      skip();
      if (peek() == '\0') break;
      block_.empty = false;
      statement();
    }
  }

 private:
  char peek(std::size_t ahead = 0) const { return pos_ + ahead < text_.size() ? text_[pos_ + ahead] : '\0'; }
  void skip() { expr_.skip_blanks(); }

  std::string identifier() {
    std::string name;
    while (is_ident(peek())) name += text_[pos_++];
    return name;
  }

  void read_label() {
    // NAME: with a name of at least two characters, starting with a letter or '_' (840D labels).
    std::size_t k = pos_;
    if (!(is_upper(peek()) || peek() == '_')) return;
    while (k < text_.size() && is_ident(text_[k])) ++k;
    if (k < text_.size() && text_[k] == ':' && k - pos_ >= 2) {
      block_.label = std::string(text_.substr(pos_, k - pos_));
      pos_ = k + 1;
      block_.empty = false;
    }
  }

  std::string string_literal() {
    if (peek() != '"') throw LineError("expected a string in double quotes but found " + show(peek()));
    ++pos_;
    const std::size_t end = text_.find('"', pos_);
    if (end == std::string_view::npos) throw LineError("a string has no closing '\"'");
    std::string s(original_.substr(pos_, end - pos_));
    pos_ = end + 1;
    return s;
  }

 public:
  std::string_view original_;  // the line as written (strings keep their case)

 private:
  // Address letters that take a numeric constant directly ("X-14.5", "G0").
  static bool constant_address(char c) {
    return std::string_view("ABCDFGHIJKMSTXYZ").find(c) != std::string_view::npos;
  }
  static bool axis_letter(char c) { return std::string_view("XYZABCIJK").find(c) != std::string_view::npos; }

  void statement() {
    const char c = peek();
    if (!is_ident_start(c)) throw LineError("unexpected " + show(c));
    // Address with a constant: one letter, then a digit, '.', or a sign followed by one.
    const char n1 = peek(1), n2 = peek(2);
    const bool number_follows = is_digit(n1) || n1 == '.' || ((n1 == '-' || n1 == '+') && (is_digit(n2) || n2 == '.'));
    if (c == 'R' && is_digit(n1)) {
      r_parameter();
      return;
    }
    if (constant_address(c) && number_follows) {
      ++pos_;
      address_constant(c);
      return;
    }
    const std::string name = identifier();
    skip();
    if (name == "DEF") return declaration();
    if (name == "IF") return if_statement();
    if (name == "ELSE") return control_alone(Control::Else, name);
    if (name == "ENDIF") return control_alone(Control::EndIf, name);
    if (name == "WHILE") {
      block_.control = Control::While;
      block_.condition = expr_.expression();
      return;
    }
    if (name == "ENDWHILE") return control_alone(Control::EndWhile, name);
    if (name == "GOTOF" || name == "GOTOB" || name == "GOTO" || name == "GOTOC") {
      if (block_.control != Control::None) throw LineError(name + " after another control statement in one block");
      block_.control = Control::Goto;
      goto_target(name);
      return;
    }
    if (name == "MCALL") {
      block_.mcall = true;
      return;
    }
    if (name == "TRANS" || name == "ATRANS" || name == "ROT" || name == "AROT") {
      if (block_.frame != FrameOp::None) throw LineError("two frame statements in one block");
      block_.frame = name == "TRANS"    ? FrameOp::Trans
                     : name == "ATRANS" ? FrameOp::ATrans
                     : name == "ROT"    ? FrameOp::Rot
                                        : FrameOp::ARot;
      return;
    }
    if (peek() == '=') {
      ++pos_;
      skip();
      return address_expression(name);
    }
    if (peek() == '(') return call(name);
    if (std::find(kKeywords.begin(), kKeywords.end(), name) != kKeywords.end()) {
      block_.keywords.push_back({name, static_cast<int>(pos_ - name.size()) + 1});
      return;
    }
    throw LineError("unknown word \"" + name + "\"");
  }

  void control_alone(Control kind, const std::string& name) {
    if (block_.control != Control::None) throw LineError(name + " after another control statement in one block");
    block_.control = kind;
  }

  void goto_target(const std::string& kw) {
    block_.goto_kind = kw == "GOTOF"   ? GotoKind::Forward
                       : kw == "GOTOB" ? GotoKind::Backward
                       : kw == "GOTO"  ? GotoKind::Any
                                       : GotoKind::AnyNoError;
    skip();
    std::string target = identifier();
    if (target.empty()) throw LineError(kw + " needs a label or a block number");
    block_.goto_target = target;
  }

  void if_statement() {
    block_.condition = expr_.expression();
    skip();
    if (is_ident_start(peek())) {
      const std::size_t save = pos_;
      const std::string kw = identifier();
      if (kw == "GOTOF" || kw == "GOTOB" || kw == "GOTO" || kw == "GOTOC") {
        block_.control = Control::IfGoto;
        goto_target(kw);
        return;
      }
      pos_ = save;
      throw LineError("IF on one line needs GOTOF, GOTOB, GOTO or GOTOC after its condition (or nothing: IF .. ENDIF)");
    }
    block_.control = Control::If;
  }

  void declaration() {
    const std::string type = identifier();
    if (type != "REAL" && type != "INT" && type != "BOOL")
      throw LineError("DEF " + (type.empty() ? std::string("without a type") : type) +
                      ": only REAL, INT and BOOL variables are supported");
    for (;;) {
      skip();
      const std::string name = identifier();
      if (name.empty() || name.front() == '$' || is_digit(name.front()))
        throw LineError("DEF " + type + ": expected a variable name but found " + show(peek()));
      Declaration d{type, program_.names.intern(name), name, kNoExpr};
      skip();
      if (peek() == '[') throw LineError("DEF " + type + " " + name + "[..]: arrays are not supported");
      if (peek() == '=') {
        ++pos_;
        d.init = expr_.expression();
        skip();
      }
      block_.declarations.push_back(d);
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() != '\0')
        throw LineError("DEF " + type + ": expected ',' or the end of the line but found " + show(peek()));
      return;
    }
  }

  void r_parameter() {
    ++pos_;  // 'R'
    std::string digits;
    while (is_digit(peek())) digits += text_[pos_++];
    skip();
    if (peek() != '=') throw LineError("R" + digits + " must be followed by '=' (an R parameter assignment)");
    ++pos_;
    Assignment a;
    a.index = expr_.number_node(std::stod(digits));
    a.value = expr_.expression();
    a.text = "R" + digits;
    block_.assignments.push_back(a);
  }

  void address_constant(char letter) {
    const double v = expr_.constant();
    if (letter == 'G' || letter == 'M' || letter == 'H') {
      const double r = std::round(v);
      if (std::fabs(r - v) > 1e-9 || r < 0 || r > 9999)
        throw LineError(std::string(1, letter) + expr_text(v) + " is not a valid " + letter + " function");
      (letter == 'G' ? block_.g_codes : letter == 'M' ? block_.m_codes : block_.h_codes).push_back(static_cast<int>(r));
      return;
    }
    const ExprId e = expr_.number_node(v);
    set_address(std::string(1, letter), e, AxisMode::Default);
  }

  static std::string expr_text(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
  }

  void address_expression(const std::string& name) {
    if (name == "T" && peek() == '"') {
      if (block_.t_name || block_.t_number != kNoExpr) throw LineError("two T words in one block");
      block_.t_name = string_literal();
      return;
    }
    if (name.size() == 1 && axis_letter(name[0])) {
      AxisMode mode = AxisMode::Default;
      if ((peek() == 'A' || peek() == 'I') && peek(1) == 'C' && peek(2) == '(') {
        mode = peek() == 'A' ? AxisMode::Absolute : AxisMode::Incremental;
        pos_ += 2;
        const ExprId e = expr_.expression();  // the parenthesised value
        return set_address(name, e, mode);
      }
      return set_address(name, expr_.expression(), mode);
    }
    if (name == "F" || name == "S" || name == "D" || name == "T" || name == "CR" || name == "TURN" || name == "RPL")
      return set_address(name, expr_.expression(), AxisMode::Default);
    if (name == "G" || name == "M" || name == "H") throw LineError(name + "=<expression> is not supported");
    if (name.size() == 1 || name == "AP" || name == "RP" || name == "AR" || name == "CT" || name == "CIP")
      throw LineError("address " + name +
                      "= is not supported (polar coordinates, CIP/CT arcs and further axes are not)");
    if (name.front() == '$') throw LineError("system variable " + name + " is not supported");
    Assignment a;
    a.name = program_.names.intern(name);
    a.value = expr_.expression();
    a.text = name;
    block_.assignments.push_back(a);
  }

  void set_address(const std::string& name, ExprId e, AxisMode mode) {
    if (name.size() == 1 && axis_letter(name[0])) {
      for (const AxisWord& w : block_.axes)
        if (w.letter == name[0]) throw LineError("two " + name + " words in one block");
      block_.axes.push_back({name[0], e, mode});
      return;
    }
    ExprId* slot = name == "F"      ? &block_.f
                   : name == "S"    ? &block_.s
                   : name == "D"    ? &block_.d
                   : name == "T"    ? &block_.t_number
                   : name == "CR"   ? &block_.cr
                   : name == "TURN" ? &block_.turn
                   : name == "RPL"  ? &block_.rpl
                                    : nullptr;
    if (slot == nullptr) throw LineError("unknown address " + name);
    if (*slot != kNoExpr || (name == "T" && block_.t_name)) throw LineError("two " + name + " words in one block");
    *slot = e;
  }

  void call(const std::string& name) {
    if (block_.call) throw LineError("two procedure calls in one block");
    Call c;
    c.name = name;
    ++pos_;  // '('
    skip();
    if (peek() == ')') {
      ++pos_;
      block_.call = std::move(c);
      return;
    }
    for (;;) {
      skip();
      if (peek() == ',' || peek() == ')') {  // an argument left out
        c.args.push_back(kNoExpr);
        c.string_args.emplace_back();
      } else if (peek() == '"') {
        c.args.push_back(kNoExpr);
        c.string_args.push_back(string_literal());
      } else {
        c.args.push_back(expr_.expression());
        c.string_args.emplace_back();
      }
      skip();
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() == ')') {
        ++pos_;
        break;
      }
      throw LineError(name + "(): expected ',' or ')' but found " + show(peek()));
    }
    block_.call = std::move(c);
  }

  std::string_view text_;
  std::size_t pos_ = 0;
  Block& block_;
  Program& program_;
  ExprReader expr_;
};

// The line in upper case (strings keep their case) and its comment.
void split_line(std::string_view raw, std::string& code, std::string& original, std::string& comment) {
  bool in_string = false;
  std::size_t end = raw.size();
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const char c = raw[i];
    if (c == '"') in_string = !in_string;
    if (c == ';' && !in_string) {
      end = i;
      comment = trim(raw.substr(i + 1));
      break;
    }
  }
  original.assign(raw.substr(0, end));
  while (!original.empty() && (original.back() == '\r' || original.back() == ' ' || original.back() == '\t'))
    original.pop_back();
  code.resize(original.size());
  in_string = false;
  for (std::size_t i = 0; i < original.size(); ++i) {
    const char c = original[i];
    if (c == '"') in_string = !in_string;
    code[i] = in_string ? c : upper(c);
  }
}

}  // namespace

Program parse_program(std::string_view text) {
  Program program;
  std::size_t start = 0;
  int number = 0;
  while (start <= text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    if (start == text.size() && end == start) break;  // no empty line after a final newline
    const std::string_view raw = text.substr(start, end - start);
    Block block;
    block.number = ++number;
    std::string code, original;
    split_line(raw, code, original, block.comment);
    if (!block.comment.empty()) block.empty = false;
    try {
      LineReader reader(code, block, program);
      reader.original_ = original;
      reader.read();
    } catch (const LineError& e) {
      block.error = e.what();
      block.empty = false;
    } catch (const gcode::ExprError& e) {
      block.error = e.what();
      block.empty = false;
    }
    program.blocks.push_back(std::move(block));
    start = end + 1;
  }
  return program;
}

bool looks_like_sinumerik(std::string_view text) {
  // Statements only the 840D dialect has; comments (after ';' or inside '(' ')') are not looked at.
  static constexpr std::string_view kMarkers[] = {"DEF ", "MSG(", "MSG (",  "CYCLE", "TRAORI", "TRAFOOF",
                                                  "SUPA", "T=\"", "GOTOF",  "GOTOB", "=AC(",   "=IC(",
                                                  "CR=",  "AROT", "ATRANS", "ENDIF", "G642",   "G710"};
  std::size_t start = 0;
  for (int lines = 0; lines < 400 && start < text.size(); ++lines) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string code;
    bool in_paren = false;
    for (std::size_t i = start; i < end; ++i) {
      const char c = text[i];
      if (c == ';') break;
      if (c == '(' && !in_paren) {
        // A call has a name of two letters or more before '(' (CYCLE832(, MSG(, AC(); RS274's comments do not.
        std::size_t k = code.size(), letters = 0;
        while (k > 0 && is_ident(code[k - 1])) letters += is_upper(code[--k]) ? 1 : 0;
        if (letters < 2) in_paren = true;
      }
      if (!in_paren) code += upper(c);
      if (c == ')') in_paren = false;
    }
    for (std::string_view m : kMarkers) {
      const std::size_t at = code.find(m);
      if (at == std::string::npos) continue;
      // a whole word: not preceded by a letter ("CYCLE" in "RECYCLE" is not a marker)
      if (at > 0 && is_upper(code[at - 1]) && m != "=AC(" && m != "=IC(" && m != "T=\"") continue;
      return true;
    }
    start = end + 1;
  }
  return false;
}

}  // namespace vmsim::program::sinumerik
