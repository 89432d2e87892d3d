#include "program/gcode_expr.hpp"
#include "core/units.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace vmsim::program::gcode {

namespace {

// LinuxCNC converts angles with the long double M_PIl; doing the same keeps results bit-identical with `rs274`.
using core::units::kPiLong;

double deg_to_rad(double deg) { return static_cast<double>((static_cast<long double>(deg) * kPiLong) / 180.0L); }
double rad_to_deg(double rad) { return static_cast<double>((static_cast<long double>(rad) * 180.0L) / kPiLong); }

int precedence(BinaryOp op) {
  switch (op) {
    case BinaryOp::Power:
      return 6;
    case BinaryOp::Times:
    case BinaryOp::Divide:
    case BinaryOp::Modulo:
      return 5;
    case BinaryOp::Plus:
    case BinaryOp::Minus:
      return 4;
    case BinaryOp::Eq:
    case BinaryOp::Ne:
    case BinaryOp::Gt:
    case BinaryOp::Ge:
    case BinaryOp::Lt:
    case BinaryOp::Le:
      return 3;
    case BinaryOp::And:
    case BinaryOp::Or:
    case BinaryOp::Xor:
      return 2;
  }
  return 0;
}

std::string show(char c) {
  if (c == '\0') return "end of line";
  if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) return "a non-printable character";
  return std::string("'") + c + "'";
}

double check_finite(double v) {
  if (!std::isfinite(v)) throw ExprError("the result is not a finite number (overflow)");
  return v;
}

double unary(UnaryFn fn, double x) {
  switch (fn) {
    case UnaryFn::Abs:
      return std::fabs(x);
    case UnaryFn::Acos:
      if (x < -1.0 || x > 1.0) throw ExprError("argument to ACOS is outside [-1, 1]");
      return rad_to_deg(std::acos(x));
    case UnaryFn::Asin:
      if (x < -1.0 || x > 1.0) throw ExprError("argument to ASIN is outside [-1, 1]");
      return rad_to_deg(std::asin(x));
    case UnaryFn::Cos:
      return std::cos(deg_to_rad(x));
    case UnaryFn::Exp:
      return std::exp(x);
    case UnaryFn::Fix:
      return std::floor(x);
    case UnaryFn::Fup:
      return std::ceil(x);
    // LinuxCNC: (int)(x + (x < 0 ? -0.5 : 0.5)); trunc gives the same without int overflow.
    case UnaryFn::Round:
      return std::trunc(x + (x < 0.0 ? -0.5 : 0.5));
    case UnaryFn::Ln:
      if (x <= 0.0) throw ExprError("argument to LN is zero or negative");
      return std::log(x);
    case UnaryFn::Sin:
      return std::sin(deg_to_rad(x));
    case UnaryFn::Sqrt:
      if (x < 0.0) throw ExprError("argument to SQRT is negative");
      return std::sqrt(x);
    case UnaryFn::Tan:
      return std::tan(deg_to_rad(x));
    case UnaryFn::Trunc:
      return std::trunc(x);
  }
  return x;
}

double binary(BinaryOp op, double l, double r) {
  switch (op) {
    case BinaryOp::Power:
      if (l < 0.0 && std::floor(r) != r) throw ExprError("negative number raised to a non-integer power");
      return std::pow(l, r);
    case BinaryOp::Times:
      return l * r;
    case BinaryOp::Divide:
      if (r == 0.0) throw ExprError("division by zero");
      return l / r;
    case BinaryOp::Modulo: {
      if (r == 0.0) throw ExprError("MOD by zero");
      double m = std::fmod(l, r);  // LinuxCNC always returns a non-negative result
      if (m < 0.0) m += std::fabs(r);
      return m;
    }
    case BinaryOp::Plus:
      return l + r;
    case BinaryOp::Minus:
      return l - r;
    case BinaryOp::Eq:
      return std::fabs(l - r) < kToleranceEqual ? 1.0 : 0.0;
    case BinaryOp::Ne:
      return std::fabs(l - r) >= kToleranceEqual ? 1.0 : 0.0;
    case BinaryOp::Gt:
      return l > r ? 1.0 : 0.0;
    case BinaryOp::Ge:
      return (std::fabs(l - r) < kToleranceEqual || l >= r) ? 1.0 : 0.0;
    case BinaryOp::Lt:
      return l < r ? 1.0 : 0.0;
    case BinaryOp::Le:
      return (std::fabs(l - r) < kToleranceEqual || l <= r) ? 1.0 : 0.0;
    case BinaryOp::And:
      return (l == 0.0 || r == 0.0) ? 0.0 : 1.0;
    case BinaryOp::Or:
      return (l != 0.0 || r != 0.0) ? 1.0 : 0.0;
    case BinaryOp::Xor:
      return ((l == 0.0) != (r == 0.0)) ? 1.0 : 0.0;
  }
  return 0.0;
}

struct DepthGuard {
  explicit DepthGuard(int& depth) : depth_(depth) {
    if (++depth_ > kMaxBracketDepth)
      throw ExprError("expression nested more than " + std::to_string(kMaxBracketDepth) + " levels deep");
  }
  ~DepthGuard() { --depth_; }
  DepthGuard(const DepthGuard&) = delete;
  DepthGuard& operator=(const DepthGuard&) = delete;
  int& depth_;
};

}  // namespace

int NameTable::intern(const std::string& name) {
  auto [it, inserted] = ids_.try_emplace(name, static_cast<int>(names_.size()));
  if (inserted) names_.push_back(name);
  return it->second;
}

ExprId ExprPool::add(const ExprNode& node) {
  nodes_.push_back(node);
  return static_cast<ExprId>(nodes_.size() - 1);
}

double ExprPool::evaluate(ExprId id, const ParamSource& params) const { return check_finite(eval(id, params)); }

double ExprPool::eval(ExprId id, const ParamSource& params) const {
  const ExprNode& n = (*this)[id];
  switch (n.op) {
    case ExprOp::Number:
      return n.number;
    case ExprOp::Param:
      return params.numbered(eval(n.lhs, params));
    case ExprOp::NamedParam:
      return params.named(n.name);
    case ExprOp::Exists:
      return params.exists(n.name) ? 1.0 : 0.0;
    case ExprOp::Negate:
      return -eval(n.lhs, params);
    case ExprOp::Unary:
      return check_finite(unary(static_cast<UnaryFn>(n.fn), eval(n.lhs, params)));
    case ExprOp::Atan2: {
      const double y = eval(n.lhs, params);
      const double x = eval(n.rhs, params);
      return rad_to_deg(std::atan2(y, x));
    }
    case ExprOp::Binary: {
      const double l = eval(n.lhs, params);
      const double r = eval(n.rhs, params);
      return check_finite(binary(static_cast<BinaryOp>(n.fn), l, r));
    }
  }
  return 0.0;
}

ExprId ExprParser::make(ExprNode node) {
  int h = 0;
  if (node.lhs != kNoExpr) h = std::max<int>(h, pool_[node.lhs].height);
  if (node.rhs != kNoExpr) h = std::max<int>(h, pool_[node.rhs].height);
  if (h + 1 > kMaxTreeHeight)
    throw ExprError("expression has more than " + std::to_string(kMaxTreeHeight) + " nested operations");
  node.height = static_cast<std::int16_t>(h + 1);
  return pool_.add(node);
}

ExprId ExprParser::value() {
  DepthGuard guard(depth_);
  const char c = peek();
  if (c == '\0') throw ExprError("a value is missing at the end of the line");
  if (c == '[') return bracketed();
  if (c == '#') {
    ++pos_;
    if (peek() == '<') return make({.op = ExprOp::NamedParam, .name = named_param_name()});
    const ExprId index = value();
    return make({.op = ExprOp::Param, .lhs = index});
  }
  // A sign before a digit belongs to the number; before anything else it is a unary operator that binds
  // tighter than **, as in LinuxCNC: [-2**2] is 4.
  if ((c == '-' || c == '+') && !is_digit(peek(1)) && peek(1) != '.') {
    ++pos_;
    const ExprId operand = value();
    return c == '-' ? make({.op = ExprOp::Negate, .lhs = operand}) : operand;
  }
  if (is_lower(c)) {
    std::string name;
    while (is_lower(peek())) name += text_[pos_++];
    return function(name);
  }
  return number();
}

int ExprParser::named_param_name() {
  // at '<'; the name runs to '>' (blanks were already removed and letters lowered, as LinuxCNC does)
  ++pos_;
  const std::size_t end = text_.find('>', pos_);
  if (end == std::string_view::npos)
    throw ExprError("named parameter #<" + std::string(text_.substr(pos_)) + " has no closing '>'");
  if (end == pos_) throw ExprError("named parameter #<> has an empty name");
  const std::string name(text_.substr(pos_, end - pos_));
  pos_ = end + 1;
  return names_.intern(name);
}

ExprId ExprParser::bracketed() {
  DepthGuard guard(depth_);
  if (peek() != '[') throw ExprError("expected '[' but found " + show(peek()));
  ++pos_;
  const ExprId e = expression(0);
  if (peek() != ']') throw ExprError("expected ']' or an operator but found " + show(peek()));
  ++pos_;
  return e;
}

bool ExprParser::peek_operator(BinaryOp& op, std::size_t& length) const {
  const std::string_view rest = text_.substr(pos_);
  struct Token {
    std::string_view text;
    BinaryOp op;
  };
  // Longer spellings first ("**" before "*", "xor" before "or").
  static constexpr Token kTokens[] = {
      {"**", BinaryOp::Power}, {"*", BinaryOp::Times}, {"/", BinaryOp::Divide}, {"mod", BinaryOp::Modulo},
      {"+", BinaryOp::Plus},   {"-", BinaryOp::Minus}, {"eq", BinaryOp::Eq},    {"ne", BinaryOp::Ne},
      {"gt", BinaryOp::Gt},    {"ge", BinaryOp::Ge},   {"lt", BinaryOp::Lt},    {"le", BinaryOp::Le},
      {"and", BinaryOp::And},  {"xor", BinaryOp::Xor}, {"or", BinaryOp::Or},
  };
  for (const Token& t : kTokens) {
    if (rest.starts_with(t.text)) {
      op = t.op;
      length = t.text.size();
      return true;
    }
  }
  return false;
}

ExprId ExprParser::expression(int min_prec) {
  ExprId lhs = value();
  for (;;) {
    BinaryOp op{};
    std::size_t length = 0;
    if (!peek_operator(op, length)) break;
    const int prec = precedence(op);
    if (prec < min_prec) break;
    pos_ += length;
    const ExprId rhs = expression(prec + 1);
    lhs = make({.op = ExprOp::Binary, .fn = static_cast<std::uint8_t>(op), .lhs = lhs, .rhs = rhs});
  }
  return lhs;
}

ExprId ExprParser::function(const std::string& name) {
  struct Fn {
    std::string_view name;
    UnaryFn fn;
  };
  static constexpr Fn kFns[] = {
      {"abs", UnaryFn::Abs}, {"acos", UnaryFn::Acos}, {"asin", UnaryFn::Asin}, {"cos", UnaryFn::Cos},
      {"exp", UnaryFn::Exp}, {"fix", UnaryFn::Fix},   {"fup", UnaryFn::Fup},   {"round", UnaryFn::Round},
      {"ln", UnaryFn::Ln},   {"sin", UnaryFn::Sin},   {"sqrt", UnaryFn::Sqrt}, {"tan", UnaryFn::Tan},
  };
  if (name == "atan") {
    // ATAN[y]/[x]: LinuxCNC's only two-argument function.
    const ExprId y = bracketed();
    if (peek() != '/') throw ExprError("ATAN needs the form ATAN[y]/[x]");
    ++pos_;
    const ExprId x = bracketed();
    return make({.op = ExprOp::Atan2, .lhs = y, .rhs = x});
  }
  if (name == "exists") {
    if (peek() != '[' || peek(1) != '#' || peek(2) != '<') throw ExprError("EXISTS needs the form EXISTS[#<name>]");
    pos_ += 2;
    const int id = named_param_name();
    if (peek() != ']') throw ExprError("EXISTS needs the form EXISTS[#<name>]");
    ++pos_;
    return make({.op = ExprOp::Exists, .name = id});
  }
  for (const Fn& f : kFns) {
    if (name == f.name) {
      const ExprId arg = bracketed();
      return make({.op = ExprOp::Unary, .fn = static_cast<std::uint8_t>(f.fn), .lhs = arg});
    }
  }
  throw ExprError("unknown function or misplaced letters \"" + name + "\"");
}

ExprId ExprParser::number() {
  const std::size_t start = pos_;
  bool negative = false;
  if (peek() == '+' || peek() == '-') {
    negative = peek() == '-';
    ++pos_;
  }
  std::string digits;
  std::size_t n_digits = 0;
  while (is_digit(peek())) {
    digits += text_[pos_++];
    ++n_digits;
  }
  if (digits.empty()) digits.push_back('0');
  if (peek() == '.') {
    digits += text_[pos_++];
    while (is_digit(peek())) {
      digits += text_[pos_++];
      ++n_digits;
    }
  }
  if (n_digits == 0) {
    pos_ = start;
    throw ExprError("expected a number but found " + show(peek()));
  }
  double v = 0.0;
  const auto res = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (res.ec != std::errc() || !std::isfinite(v))
    throw ExprError("number " + std::string(text_.substr(start, pos_ - start)) + " is out of range");
  return make({.op = ExprOp::Number, .number = negative ? -v : v});
}

}  // namespace vmsim::program::gcode
