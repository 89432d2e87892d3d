// Program flow: '%' framing, the main loop with its guards, and O-word control flow (subroutines, if,
// while, do-while, repeat, break, continue), matched once over the whole file.
#include "core/error.hpp"
#include "program/gcode_interp.hpp"

#include <cmath>

namespace vmsim::program::gcode {

namespace {

bool is_loop(OKind k) { return k == OKind::While || k == OKind::Do || k == OKind::Repeat; }

const char* closer(OKind k) {
  switch (k) {
    case OKind::Sub:
      return "endsub";
    case OKind::If:
    case OKind::ElseIf:
    case OKind::Else:
      return "endif";
    case OKind::While:
      return "endwhile";
    case OKind::Do:
      return "while";
    case OKind::Repeat:
      return "endrepeat";
    default:
      return "?";
  }
}

}  // namespace

void Interpreter::build_flow() {
  const auto& lines = prog_.lines;
  const std::size_t n = lines.size();
  // '%' framing: an opening '%' on the first line with content makes the next '%' line the end.
  end_line_ = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (!lines[i].has_content && !lines[i].percent) continue;
    if (lines[i].percent) {
      percent_mode_ = true;
      first_line_ = i + 1;
      for (std::size_t j = i + 1; j < n; ++j)
        if (lines[j].percent) {
          end_line_ = j;
          break;
        }
    }
    break;
  }

  match_.assign(n, -1);
  do_end_.assign(n, 0);
  flow_error_.assign(n, std::string());
  struct Open {
    OKind kind;
    std::string label;
    std::size_t line;
    std::size_t last_branch;
  };
  std::vector<Open> open;
  const auto where = [&](const Open& o) {
    return oword_name(o.label) + " " + oword_keyword(o.kind) + " (line " + std::to_string(lines[o.line].number) + ")";
  };
  for (std::size_t i = first_line_; i < end_line_; ++i) {
    // An O-word line that cannot be read (a bad expression on a repeat, while or if) would leave its closing line
    // unmatched; its own error, on its own line, is the one to report (issue 18).
    if (lines[i].unreadable_oword) flow_error_[i] = lines[i].error;
    if (!lines[i].oword) continue;
    const OWord& o = *lines[i].oword;
    const std::string name = oword_name(o.label) + " " + oword_keyword(o.kind);
    const auto closes = [&](std::initializer_list<OKind> kinds) -> Open* {
      if (open.empty()) {
        flow_error_[i] = name + " has no matching opening O-word";
        return nullptr;
      }
      Open& top = open.back();
      bool kind_ok = false;
      for (OKind k : kinds) kind_ok = kind_ok || top.kind == k;
      if (!kind_ok || top.label != o.label) {
        flow_error_[i] = name + " does not match the innermost open block, " + where(top);
        return nullptr;
      }
      return &top;
    };
    switch (o.kind) {
      case OKind::Sub: {
        if (!open.empty())
          flow_error_[i] = name + " is inside " + where(open.back()) + "; subroutines must be defined at the top level";
        const auto [it, inserted] = subs_.try_emplace(o.label, i);
        if (!inserted && flow_error_[i].empty())
          flow_error_[i] = name + " is defined twice (first on line " + std::to_string(lines[it->second].number) + ")";
        open.push_back({o.kind, o.label, i, i});
        break;
      }
      case OKind::EndSub:
        if (Open* top = closes({OKind::Sub})) {
          match_[top->line] = static_cast<int>(i);
          match_[i] = static_cast<int>(top->line);
          open.pop_back();
        }
        break;
      case OKind::Return: {
        bool found = false;
        for (auto it = open.rbegin(); it != open.rend(); ++it)
          if (it->kind == OKind::Sub) {
            found = it->label == o.label;
            if (found) match_[i] = static_cast<int>(it->line);
            break;
          }
        if (!found) flow_error_[i] = name + " is not inside " + oword_name(o.label) + " sub";
        break;
      }
      case OKind::If:
        open.push_back({o.kind, o.label, i, i});
        break;
      case OKind::ElseIf:
      case OKind::Else:
        if (Open* top = closes({OKind::If})) {
          if (lines[top->last_branch].oword->kind == OKind::Else) {
            flow_error_[i] = name + " after " + oword_name(o.label) + " else";
            break;
          }
          match_[top->last_branch] = static_cast<int>(i);
          top->last_branch = i;
        }
        break;
      case OKind::EndIf:
        if (Open* top = closes({OKind::If})) {
          match_[top->last_branch] = static_cast<int>(i);
          open.pop_back();
        }
        break;
      case OKind::While:
        // The end of a do-while, or the head of a while loop.
        if (!open.empty() && open.back().kind == OKind::Do && open.back().label == o.label) {
          match_[open.back().line] = static_cast<int>(i);
          match_[i] = static_cast<int>(open.back().line);
          do_end_[i] = 1;
          open.pop_back();
        } else {
          open.push_back({o.kind, o.label, i, i});
        }
        break;
      case OKind::EndWhile:
        if (Open* top = closes({OKind::While})) {
          match_[top->line] = static_cast<int>(i);
          match_[i] = static_cast<int>(top->line);
          open.pop_back();
        }
        break;
      case OKind::Do:
      case OKind::Repeat:
        open.push_back({o.kind, o.label, i, i});
        break;
      case OKind::EndRepeat:
        if (Open* top = closes({OKind::Repeat})) {
          match_[top->line] = static_cast<int>(i);
          match_[i] = static_cast<int>(top->line);
          open.pop_back();
        }
        break;
      case OKind::Break:
      case OKind::Continue: {
        bool found = false;
        for (auto it = open.rbegin(); it != open.rend() && it->kind != OKind::Sub; ++it)
          if (is_loop(it->kind) && it->label == o.label) {
            match_[i] = static_cast<int>(it->line);
            found = true;
            break;
          }
        if (!found) flow_error_[i] = name + " is not inside an " + oword_name(o.label) + " loop";
        break;
      }
      case OKind::Call:
        break;
    }
  }
  // Mismatches found on the way explain blocks left open, so they are the ones to report first.
  for (std::size_t i = first_line_; i < end_line_ && first_flow_error_ < 0; ++i)
    if (!flow_error_[i].empty()) first_flow_error_ = static_cast<long>(i);
  for (const Open& o : open)
    if (flow_error_[o.line].empty())
      flow_error_[o.line] = where(o) + " has no matching " + oword_name(o.label) + " " + closer(o.kind);
}

bool Interpreter::eval_condition(std::size_t idx) {
  const OWord& o = *prog_.lines[idx].oword;
  try {
    return prog_.exprs.evaluate(o.expr, *this) != 0.0;
  } catch (const ExprError& e) {
    fail(oword_name(o.label) + " " + oword_keyword(o.kind) + ": " + e.what());
  }
}

std::size_t Interpreter::exec_oword(std::size_t idx) {
  const OWord& o = *prog_.lines[idx].oword;
  // Built only for messages: loops pass here millions of times.
  const auto name = [&o] { return oword_name(o.label) + " " + oword_keyword(o.kind); };
  if (!flow_error_[idx].empty()) fail(flow_error_[idx]);
  const auto jump = [&](std::size_t i) { return static_cast<std::size_t>(match_[i]); };
  switch (o.kind) {
    case OKind::Sub:
      return jump(idx) + 1;  // a definition: skip its body
    case OKind::EndSub:
    case OKind::Return: {
      const std::size_t sub_line = jump(idx);  // endsub and return both point at their sub
      if (frames_.size() < 2 || frames_.back().sub_line != static_cast<int>(sub_line))
        fail(name() + " reached without a call of " + oword_name(o.label));
      double value = 0.0;
      const bool has_value = o.expr != kNoExpr;
      if (has_value) {
        try {
          value = prog_.exprs.evaluate(o.expr, *this);
        } catch (const ExprError& e) {
          fail(name() + ": " + e.what());
        }
      }
      Frame& f = frames_.back();
      for (std::size_t i = 0; i < 30; ++i) params_[1 + i] = f.saved_args[i];
      const std::size_t back = static_cast<std::size_t>(f.return_line);
      frames_.pop_back();
      // #<_value> and #<_value_returned> tell the caller what the subroutine returned.
      if (value_returned_id_ >= 0) globals_[static_cast<std::size_t>(value_returned_id_)] = has_value ? 1.0 : 0.0;
      if (value_id_ >= 0 && has_value) globals_[static_cast<std::size_t>(value_id_)] = value;
      return back;
    }
    case OKind::Call: {
      const auto it = subs_.find(o.label);
      if (it == subs_.end())
        fail(name() + ": there is no " + oword_name(o.label) + " sub in " + file_ +
             " (subroutines in separate files are not supported)");
      if (!flow_error_[it->second].empty()) {
        line_ = it->second;
        fail(flow_error_[it->second]);
      }
      if (frames_.size() > kMaxCallDepth)
        fail(name() + ": subroutines nested more than " + std::to_string(kMaxCallDepth) + " deep (endless recursion?)");
      std::array<double, 30> args{};
      for (std::size_t i = 0; i < o.args.size(); ++i) {
        try {
          args[i] = prog_.exprs.evaluate(o.args[i], *this);
        } catch (const ExprError& e) {
          fail(name() + " argument " + std::to_string(i + 1) + ": " + e.what());
        }
      }
      Frame f;
      f.sub_line = static_cast<int>(it->second);
      f.return_line = static_cast<int>(idx + 1);
      for (std::size_t i = 0; i < 30; ++i) {
        f.saved_args[i] = params_[1 + i];
        params_[1 + i] = args[i];  // #1..#30; arguments not given are 0
      }
      frames_.push_back(std::move(f));
      return it->second + 1;
    }
    case OKind::If: {
      if (eval_condition(idx)) return idx + 1;
      std::size_t j = jump(idx);
      while (prog_.lines[j].oword->kind == OKind::ElseIf) {
        line_ = j;
        if (eval_condition(j)) return j + 1;
        j = jump(j);
      }
      return j + 1;  // after else, or after endif
    }
    case OKind::ElseIf:
    case OKind::Else: {
      // The branch before was taken: go past the endif.
      std::size_t j = idx;
      while (prog_.lines[j].oword->kind != OKind::EndIf) j = jump(j);
      return j + 1;
    }
    case OKind::EndIf:
    case OKind::Do:
      return idx + 1;
    case OKind::While:
      if (do_end_[idx]) return eval_condition(idx) ? jump(idx) + 1 : idx + 1;
      return eval_condition(idx) ? idx + 1 : jump(idx) + 1;
    case OKind::EndWhile:
      return jump(idx);  // back to the while, which tests again
    case OKind::Repeat: {
      double count = 0.0;
      try {
        count = prog_.exprs.evaluate(o.expr, *this);
      } catch (const ExprError& e) {
        fail(name() + ": " + e.what());
      }
      const double n = std::nearbyint(count);
      if (n < 1.0) return jump(idx) + 1;
      frames_.back().repeat_left[static_cast<int>(idx)] = static_cast<long long>(std::min(n, 1e18));
      return idx + 1;
    }
    case OKind::EndRepeat: {
      const std::size_t head = jump(idx);
      auto& left = frames_.back().repeat_left;
      const auto it = left.find(static_cast<int>(head));
      if (it != left.end() && --it->second > 0) return head + 1;
      if (it != left.end()) left.erase(it);
      return idx + 1;
    }
    case OKind::Break: {
      const std::size_t head = jump(idx);
      frames_.back().repeat_left.erase(static_cast<int>(head));
      return jump(head) + 1;  // past endwhile / the do's while / endrepeat
    }
    case OKind::Continue: {
      const std::size_t head = jump(idx);
      // while: test again at the head; do-while and repeat: at their end line (test / count down).
      return prog_.lines[head].oword->kind == OKind::While ? head : jump(head);
    }
  }
  return idx + 1;
}

GcodeResult Interpreter::run() {
  build_flow();
  // A straight program makes about one call and one move per line; loops grow the vectors as they go.
  canon_.reserve(prog_.lines.size() + 16);
  path_.moves.reserve(prog_.lines.size());
  canon_.no_line();
  // What LinuxCNC's interpreter says when it starts (Interp::init, then ON_RESET), in program units (mm).
  canon_.print("USE_LENGTH_UNITS(CANON_UNITS_MM)");
  canon_.print("SET_G5X_OFFSET(1, %.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  canon_.print("SET_G92_OFFSET(%.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  canon_.print("SET_XY_ROTATION(%.4f)", 0.0);
  canon_.print("SET_FEED_REFERENCE(CANON_XYZ)");
  canon_.print("ON_RESET()");
  path_.initial_position = machine(pos_);
  tip_ = path_.initial_position;
  // A broken O-word structure is reported before anything runs, like a compiler would (unreachable code
  // included, since a skipped block is found by its structure).
  if (first_flow_error_ < 0)
    for (std::size_t i = first_line_; i < end_line_ && first_flow_error_ < 0; ++i)
      if (!flow_error_[i].empty()) first_flow_error_ = static_cast<long>(i);
  if (first_flow_error_ >= 0) {
    line_ = static_cast<std::size_t>(first_flow_error_);
    fail(flow_error_[line_]);
  }

  std::size_t idx = first_line_;
  for (;;) {
    if (idx >= end_line_) {
      if (end_line_ < prog_.lines.size()) {  // the closing '%'
        line_ = end_line_;
        canon_.set_line(prog_.lines[line_].number, prog_.lines[line_].n_word);
        if (frames_.size() > 1) fail("'%' ends the program inside a subroutine call");
        canon_.print("FINISH()");
        break;
      }
      line_ = prog_.lines.empty() ? 0 : prog_.lines.size() - 1;
      if (frames_.size() > 1) fail("the file ends inside a subroutine call (missing endsub or return?)");
      fail(percent_mode_ ? "the file ends without M2, M30 or a closing '%'"
                         : "the file ends without M2 or M30 (or '%' framing)");
    }
    line_ = idx;
    const SourceLine& line = prog_.lines[idx];
    if (++blocks_ > options_.max_blocks)
      fail("more than " + std::to_string(options_.max_blocks) + " blocks executed: possible endless loop");
    if (!line.error.empty()) fail(line.error);
    if (line.percent) fail("'%' may only stand alone on the first and the last line of the program");
    if (!line.has_content || (line.block_delete && options_.block_delete)) {
      ++idx;
      continue;
    }
    canon_.set_line(line.number, line.n_word);
    if (line.oword) {
      idx = exec_oword(idx);
      continue;
    }
    if (line.words.empty() && !line.comment) {  // only parameter settings: nothing else to execute
      apply_assignments(line);
      ++idx;
      continue;
    }
    Block b = read_block(line);
    apply_assignments(line);
    if (execute_block(b)) break;
    ++idx;
  }
  canon_.no_line();
  canon_.print("ON_RESET()");
  canon_.print("ON_RESET()");

  if (!diameter_from_feed_ && tools_ != nullptr && current_tool_ != 0)
    if (const ToolEntry* t = tools_->find(current_tool_))
      path_.tool_diameter_mm = options_.inch_machine ? t->diameter * 25.4 : t->diameter;
  GcodeResult result;
  result.path = std::move(path_);
  result.canon = canon_.take();
  return result;
}

}  // namespace vmsim::program::gcode
