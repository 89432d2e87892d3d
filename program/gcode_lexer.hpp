#pragma once
// Reading RS274/NGC lines into blocks (internal to the G-code reader).
//
// Each physical line is read once, as LinuxCNC reads it: case-insensitive, blanks ignored outside comments,
// ( ) comments (the last one of a line is the one executed), ';' comments to the end of the line, a leading
// '/' for block delete, an optional N number, then either an O-word or words and parameter settings.
// Word values stay expression trees; they are evaluated each time the line executes.
// A line that cannot be read keeps its error and raises it only when it is executed, so that text LinuxCNC
// never reaches (after M2, inside a skipped subroutine) does not stop the program either.
#include "program/gcode_expr.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vmsim::program::gcode {

struct Word {
  char letter = 'G';  // uppercase
  ExprId value = kNoExpr;
};

// #n=value or #<name>=value. The target index is an expression too (#[#1+1]=...).
struct Assignment {
  int name = -1;  // >= 0: named parameter (interned id)
  ExprId index = kNoExpr;
  ExprId value = kNoExpr;
};

enum class OKind : std::uint8_t {
  Sub,
  EndSub,
  Return,
  Call,
  If,
  ElseIf,
  Else,
  EndIf,
  While,
  EndWhile,
  Do,
  Repeat,
  EndRepeat,
  Break,
  Continue
};

struct OWord {
  OKind kind = OKind::Sub;
  std::string label;         // "100" or "<name>" (as written after O, numbers without leading zeros)
  std::vector<ExprId> args;  // call arguments
  ExprId expr = kNoExpr;     // condition, repeat count, return value
};

struct SourceLine {
  int number = 0;                 // 1-based line of the file
  std::string n_word = "N.....";  // what rs274 prints for the line: "N....." or 'N' and the digits written
  bool percent = false;           // a line holding only '%'
  bool block_delete = false;      // starts with '/'
  bool has_content = false;       // anything to execute (words, settings, a comment or an O-word)
  std::vector<Word> words;
  std::vector<Assignment> assignments;
  std::optional<std::string> comment;  // text inside the last ( ) of the line, as written
  std::optional<OWord> oword;
  std::string error;  // non-empty: why the line cannot be read
  // An O-word line that could not be read (its error above): the flow matcher reports it, not the end of its block.
  bool unreadable_oword = false;
};

struct ParsedProgram {
  std::vector<SourceLine> lines;
  ExprPool exprs;
  NameTable names;
};

// Splits the text into lines (LF or CRLF) and reads each one.
ParsedProgram parse_program(std::string_view text);

// "o100", "o<name>" for messages.
std::string oword_name(const std::string& label);
const char* oword_keyword(OKind kind);

}  // namespace vmsim::program::gcode
