#pragma once
// Reading Siemens 840D sl part programs into blocks (internal to the Sinumerik reader).
//
// Each line is read once, as the 840D's NC language defines it (Siemens, SINUMERIK 840D sl NC programming,
// Fundamentals and Work preparation): an optional '/' (skip level), an optional block number "N10", an optional label
// "NAME:", then statements separated by blanks; ';' starts a comment to the end of the line. Keywords are
// case-insensitive. An address is one letter with a numeric constant ("X-14.543", "G0", "B90.") or an address with
// '=' and an expression ("Z=_Z_HOME", "X=AC(10)", "CR=5", "T=\"name\""). Expressions become trees of the G-code
// reader's evaluator (program/gcode_expr.hpp), evaluated each time the block executes.
// A line that cannot be read keeps its error, raised only when the line executes (a jump may skip it).
#include "program/gcode_expr.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vmsim::program::sinumerik {

using gcode::ExprId;
using gcode::kNoExpr;

enum class AxisMode : std::uint8_t { Default, Absolute /* AC() */, Incremental /* IC() */ };

// X Y Z A B C (positions) and I J K (arc centre), by letter.
struct AxisWord {
  char letter = 'X';
  ExprId value = kNoExpr;
  AxisMode mode = AxisMode::Default;
};

// var = expr, R<n> = expr.
struct Assignment {
  int name = -1;           // >= 0: a DEF variable (interned, uppercase)
  ExprId index = kNoExpr;  // R parameter number (name < 0)
  ExprId value = kNoExpr;
  std::string text;  // as written, for messages
};

struct Declaration {
  std::string type;  // REAL INT BOOL
  int name = -1;
  std::string text;
  ExprId init = kNoExpr;
};

// A procedure call: CYCLE832(_camtolerance,1,1), MSG("text"), CYCLE800().
struct Call {
  std::string name;                      // uppercase
  std::vector<ExprId> args;              // kNoExpr: argument left out ("CYCLE800(,,1)")
  std::vector<std::string> string_args;  // the string for a string argument, "" otherwise
};

enum class FrameOp : std::uint8_t { None, Trans, ATrans, Rot, ARot };

enum class Control : std::uint8_t { None, Goto, IfGoto, If, Else, EndIf, While, EndWhile };
enum class GotoKind : std::uint8_t {
  Forward /* GOTOF */,
  Backward /* GOTOB */,
  Any /* GOTO */,
  AnyNoError /* GOTOC */
};

// A keyword the reader knows, with its source column.
struct Keyword {
  std::string name;  // uppercase
  int col = 0;
};

struct Block {
  int number = 0;       // 1-based line of the file
  std::string n_word;   // "N10" as written, "" when the line has none
  std::string label;    // "NAME" of a "NAME:" label, uppercase
  bool skip = false;    // starts with '/'
  bool empty = true;    // nothing to execute (blank or comment only)
  std::string comment;  // text after ';', trimmed

  std::vector<Declaration> declarations;
  std::vector<Assignment> assignments;
  std::vector<int> g_codes;  // G numbers as written
  std::vector<int> m_codes;
  std::vector<int> h_codes;  // auxiliary functions H<n>
  std::vector<AxisWord> axes;
  ExprId f = kNoExpr, s = kNoExpr, d = kNoExpr, t_number = kNoExpr, cr = kNoExpr, turn = kNoExpr, rpl = kNoExpr;
  std::optional<std::string> t_name;  // T="name"
  std::vector<Keyword> keywords;      // TRAORI, SUPA, FFWON, ... (known, non-address commands)
  FrameOp frame = FrameOp::None;
  std::optional<Call> call;
  bool mcall = false;  // MCALL: the call (if any) becomes modal; MCALL alone ends it

  Control control = Control::None;
  GotoKind goto_kind = GotoKind::Forward;
  std::string goto_target;  // label or block number ("N100"), uppercase
  ExprId condition = kNoExpr;

  std::string error;  // non-empty: why the line cannot be read
};

struct Program {
  std::vector<Block> blocks;  // one per line of the file
  gcode::ExprPool exprs;
  gcode::NameTable names;  // DEF variables, uppercase
};

// Splits the text into lines (LF or CRLF) and reads each one.
Program parse_program(std::string_view text);

// Whether a program's text is written in the 840D dialect (DEF, MSG(, CYCLEnnn(, TRAORI, T="..", GOTOF, AC(, ...),
// looking at its first lines; used when the file's extension does not say.
bool looks_like_sinumerik(std::string_view text);

}  // namespace vmsim::program::sinumerik
