#pragma once
// RS274/NGC expressions as LinuxCNC reads them (internal to the G-code reader).
//
// A line is parsed once into small expression trees stored in one pool per program; the trees are evaluated
// every time the line executes (loops and subroutines re-run lines with new parameter values). Parsing and
// evaluation are bounded: brackets may nest kMaxBracketDepth deep and a tree may be kMaxTreeHeight high, so
// hostile input can neither overflow the stack nor make evaluation recurse without end.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace vmsim::program::gcode {

// Character classes of the G-code reader (the lexer and the expression parser; C locale, ASCII only).
inline bool is_digit(char c) { return c >= '0' && c <= '9'; }
inline bool is_lower(char c) { return c >= 'a' && c <= 'z'; }

using ExprId = std::int32_t;
inline constexpr ExprId kNoExpr = -1;
inline constexpr int kMaxBracketDepth = 64;
inline constexpr int kMaxTreeHeight = 1000;

// LinuxCNC compares EQ, NE, LE and GE with this tolerance (TOLERANCE_EQUAL of the 2.9 interpreter);
// `rs274` agrees: [1 EQ 1.00001] is 1.
inline constexpr double kToleranceEqual = 1e-4;

enum class ExprOp : std::uint8_t { Number, Param, NamedParam, Exists, Negate, Unary, Atan2, Binary };
// Trunc (towards zero) is the Sinumerik reader's TRUNC; RS274/NGC has no such function.
enum class UnaryFn : std::uint8_t {
  Abs,
  Acos,
  Asin,
  Cos,
  Exp,
  Fix,
  Fup,
  Round,
  Ln,
  Sin,
  Sqrt,
  Tan,
  Trunc
};  // ATAN is binary
// In LinuxCNC's precedence order, highest first: ** ; * / MOD ; + - ; comparisons ; AND OR XOR.
enum class BinaryOp : std::uint8_t { Power, Times, Divide, Modulo, Plus, Minus, Eq, Ne, Gt, Ge, Lt, Le, And, Or, Xor };

struct ExprNode {
  ExprOp op = ExprOp::Number;
  std::uint8_t fn = 0;      // UnaryFn or BinaryOp
  std::int16_t height = 1;  // height of the tree below and including this node
  ExprId lhs = kNoExpr;     // operand, parameter index expression, left operand, ATAN's y
  ExprId rhs = kNoExpr;     // right operand, ATAN's x
  std::int32_t name = -1;   // interned parameter name (NamedParam, Exists)
  double number = 0.0;      // Number
};

// An expression that cannot be parsed or evaluated; the caller adds the file, line and word.
struct ExprError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Named parameters are interned once at parse time; names are lowercase without spaces, as LinuxCNC keeps them.
class NameTable {
 public:
  int intern(const std::string& name);
  int find(const std::string& name) const {  // -1 if the name was never interned
    const auto it = ids_.find(name);
    return it == ids_.end() ? -1 : it->second;
  }
  const std::string& name(int id) const { return names_[static_cast<std::size_t>(id)]; }
  std::size_t size() const { return names_.size(); }

 private:
  std::unordered_map<std::string, int> ids_;
  std::vector<std::string> names_;
};

// What the evaluator needs from the interpreter. Each call throws ExprError for a bad access.
class ParamSource {
 public:
  virtual double numbered(double index) const = 0;  // #n (index as evaluated, checked by the source)
  virtual double named(int name_id) const = 0;      // #<name>
  virtual bool exists(int name_id) const = 0;       // EXISTS[#<name>]

 protected:
  ~ParamSource() = default;
};

class ExprPool {
 public:
  ExprId add(const ExprNode& node);
  const ExprNode& operator[](ExprId id) const { return nodes_[static_cast<std::size_t>(id)]; }
  bool is_number(ExprId id) const { return nodes_[static_cast<std::size_t>(id)].op == ExprOp::Number; }
  // Evaluates the tree (degrees for trigonometry, as LinuxCNC). Throws ExprError; never returns NaN or inf.
  double evaluate(ExprId id, const ParamSource& params) const;

 private:
  double eval(ExprId id, const ParamSource& params) const;
  std::vector<ExprNode> nodes_;
};

// Reads values and bracketed expressions from a normalised line (lowercase, blanks and comments removed).
// `pos` advances past what was read. Grammar (LinuxCNC's read_real_value):
//   value := '[' expr ']' | '#' param | '-' value | '+' value | function | number
//   param := '<' name '>' | value            (an index value, e.g. #3, #[1+2], ##1)
//   function := name '[' expr ']' | 'atan' '[' expr ']' '/' '[' expr ']' | 'exists' '[' '#<' name '>' ']'
//   number := [+-] digits ['.' digits]       (no exponent)
class ExprParser {
 public:
  ExprParser(std::string_view text, std::size_t& pos, ExprPool& pool, NameTable& names)
      : text_(text), pos_(pos), pool_(pool), names_(names) {}
  ExprId value();
  // '<' name '>' after a '#'; returns the interned id.
  int named_param_name();

 private:
  ExprId bracketed();               // '[' expr ']'
  ExprId expression(int min_prec);  // operator-precedence climbing, left associative at every level
  ExprId function(const std::string& name);
  ExprId number();
  bool peek_operator(BinaryOp& op, std::size_t& length) const;
  ExprId make(ExprNode node);
  char peek(std::size_t ahead = 0) const { return pos_ + ahead < text_.size() ? text_[pos_ + ahead] : '\0'; }

  std::string_view text_;
  std::size_t& pos_;
  ExprPool& pool_;
  NameTable& names_;
  int depth_ = 0;
};

}  // namespace vmsim::program::gcode
