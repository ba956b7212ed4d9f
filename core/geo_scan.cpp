#include "core/geo_scan.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "core/error.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// gmsh's lexer (Parser/Gmsh.l): parsestring copies at most 1023 characters, then reports "String
// too long" and goes on lexing after the character it dropped.
constexpr std::size_t kMaxGmshString = 1023;
// flex reads a line at a time, in pieces of up to 8192 bytes, fewer while a long token (a block
// comment) is pending; the file position a For loop or a Macro saves is the end of such a piece.
// A line longer than this, or ending a comment longer than this, is read from every position.
constexpr std::size_t kLongLine = 4000;
constexpr std::size_t kMaxWord = 64;

bool ident_start(unsigned char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}
bool is_digit(unsigned char c) {
  return c >= '0' && c <= '9';
}
bool ident_char(unsigned char c) {
  return ident_start(c) || is_digit(c);
}
bool blank(unsigned char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f';
}

enum class Kind { End, Ident, String, Number, Op };
struct Token {
  Kind kind = Kind::End;
  std::size_t begin = 0, end = 0;
  bool terminated = true;  // strings: closed by their quote
};

enum class Category { Always, Command, Include, Printf };
struct Word {
  Category category;
  const char* reason;
};

// Every word of gmsh 4.8's .geo language that reaches outside the model: Parser/Gmsh.y, rules
// Command, Printf (SendToFile), Plugin, OnelabRun, Exit, and String__Index (tStringToName).
const std::map<std::string_view, Word>& words() {
  static const std::map<std::string_view, Word> table = {
      {"Exit", {Category::Always, "ends the process"}},
      {"OnelabRun", {Category::Always, "runs a program"}},
      {"Plugin", {Category::Always, "runs a gmsh plugin, and plugins can write files"}},
      {"S2N", {Category::Always, "turns a string into a name, which can spell any command"}},
      {"StringToName",
       {Category::Always, "turns a string into a name, which can spell any command"}},
      {"SystemCall", {Category::Command, "runs a shell command"}},
      {"System", {Category::Command, "runs a shell command"}},
      {"NonBlockingSystemCall", {Category::Command, "runs a shell command"}},
      {"Save", {Category::Command, "writes a file"}},
      {"Print", {Category::Command, "writes a file"}},
      {"CreateDir", {Category::Command, "creates a folder"}},
      {"Include",
       {Category::Include, "reads a file named by an expression, which bsms cannot check"}},
      {"Merge",
       {Category::Include, "reads a file named by an expression, which bsms cannot check"}},
      {"MergeWithBoundingBox",
       {Category::Include, "reads a file named by an expression, which bsms cannot check"}},
      {"Printf", {Category::Printf, "writes a file (Printf > file)"}},
  };
  return table;
}

// A token after a command word that makes the word something else: an option category
// (Print.Width), an assignment to a variable of that name, a list element or a name with a ~{i}
// suffix. gmsh's command rules need a string expression or a name next.
bool makes_word_a_name(std::string_view op) {
  static const char* const ops[] = {".", "=", "+=", "-=", "*=", "/=", "~", "[", "++", "--"};
  for (const char* o : ops)
    if (op == o) return true;
  return false;
}

class Scanner {
 public:
  explicit Scanner(std::string_view text) : t_(text), n_(text.size()) {}

  std::vector<GeoFinding> run() {
    if (const void* nul = std::memchr(t_.data(), '\0', n_)) {
      const auto at = static_cast<std::size_t>(static_cast<const char*>(nul) - t_.data());
      add(at, "NUL", "is a NUL byte (a .geo script is text; gmsh ends strings and comments there)");
      return finish();
    }
    budget_ = 64 * static_cast<uint64_t>(n_) + (1u << 20);
    visited_.assign(n_ + 1, 0);
    queued_.assign(n_ + 1, 0);
    line_starts_.push_back(0);
    for (std::size_t i = 0; i < n_; ++i) {
      if (t_[i] == '\n') line_starts_.push_back(i + 1);
      if (t_[i] == '\n' || t_[i] == '\r') breaks_.push_back(i);
    }

    // Where gmsh may start lexing: the start of the file; where skip() / skipTest() resume,
    // wherever the words occur; the ends of flex's pieces after For / Macro / Call headers
    // (queued while lexing); every position of a line flex may read in pieces.
    lex_from(0);
    for (const char* w : {"EndIf", "EndFor", "Return", "Else"}) {
      const std::size_t len = std::strlen(w);
      for (std::size_t at = t_.find(w); at != std::string_view::npos && !out_of_budget_;
           at = t_.find(w, at + 1))
        lex_from(at + len);
    }
    for (std::size_t at = t_.find("ElseIf"); at != std::string_view::npos && !out_of_budget_;
         at = t_.find("ElseIf", at + 1))
      lex_from(at);
    for (std::size_t l = 0; l < line_starts_.size() && !out_of_budget_; ++l) {
      const std::size_t b = line_starts_[l];
      const std::size_t e = l + 1 < line_starts_.size() ? line_starts_[l + 1] : n_;
      if (e - b > kLongLine || long_comment_end_line(b, e))
        for (std::size_t p = b; p < e && !out_of_budget_; ++p) lex_from(p);
    }
    while (!queue_.empty() && !out_of_budget_) {
      const std::size_t p = queue_.back();
      queue_.pop_back();
      lex_from(p);
    }
    if (out_of_budget_)
      add(0, "(script)", "is too intricate to check (its strings, comments and lines)");
    return finish();
  }

 private:
  // Lexes in gmsh's normal mode from `p` until it reaches a position lexed before (from there on
  // the tokens are the ones already seen).
  void lex_from(std::size_t p) {
    // A start inside a word: gmsh's tokens are the rest of the word (a number may lead).
    if (p > 0 && p < n_ && ident_char(t_[p - 1]) && ident_char(t_[p])) {
      const std::size_t e = word_end(p);
      // Starts inside one word come in increasing order: the first saw every suffix.
      if (e != suffix_end_ || p < suffix_from_) {
        suffix_words(p, e);
        suffix_end_ = e;
        suffix_from_ = p;
      }
      p = e;
    }
    while (!out_of_budget_) {
      if (visited_[p]) return;
      visited_[p] = 1;
      const std::size_t q = skip_blank(p);
      if (q != p) {
        if (visited_[q]) return;
        visited_[q] = 1;
      }
      if (q >= n_) return;
      const Token tok = lex(q);
      if (tok.kind == Kind::Ident) {
        check_word(tok);
        if (is_header(text(tok))) follow_header(tok);
      }
      p = tok.end;
    }
  }

  // The end of the word (identifier characters) holding p; one forward scan per word.
  std::size_t word_end(std::size_t p) {
    if (!(p >= word_from_ && p < word_to_)) {
      word_from_ = p;
      word_to_ = p;
      while (word_to_ < n_ && ident_char(t_[word_to_])) ++word_to_;
      count(word_to_ - p);
    }
    return word_to_;
  }

  // Words that end the word [p, e) and start at or after p: tokens gmsh may read from inside it.
  void suffix_words(std::size_t p, std::size_t e) {
    auto check = [&](std::string_view w) {
      if (w.size() > e - p) return;
      const std::size_t b = e - w.size();
      if (t_.compare(b, w.size(), w) != 0) return;
      const Token tok{Kind::Ident, b, e, true};
      check_word(tok);
      if (is_header(w)) follow_header(tok);
    };
    for (const auto& entry : words()) check(entry.first);
    for (const char* h : {"For", "Macro", "Function", "Call"}) check(h);
  }

  // Whitespace and comments from p (Gmsh.l: skipcomments, skipline).
  std::size_t skip_blank(std::size_t p) {
    while (p < n_) {
      const unsigned char c = t_[p];
      if (blank(c)) {
        ++p;
      } else if (c == '/' && p + 1 < n_ && t_[p + 1] == '*') {
        const std::size_t e = close_.next(t_, p + 2);
        p = e == std::string_view::npos ? n_ : e + 2;
      } else if (c == '/' && p + 1 < n_ && t_[p + 1] == '/') {
        const std::size_t e = newline_.next(t_, p + 2);
        p = e == std::string_view::npos ? n_ : e + 1;
      } else {
        break;
      }
      count(1);
    }
    return p;
  }

  void count(uint64_t steps) {
    steps_ += steps;
    if (steps_ > budget_) out_of_budget_ = true;
  }

  // One token at q (not blank): gmsh's flex rules, longest match.
  Token lex(std::size_t q) {
    Token tok;
    tok.begin = q;
    const unsigned char c = t_[q];
    if (c == '"' || c == '\'') {
      tok.kind = Kind::String;
      const std::size_t e = t_.find(static_cast<char>(c), q + 1);
      const std::size_t stop = e == std::string_view::npos ? n_ : e;
      if (stop - (q + 1) > kMaxGmshString) {
        // gmsh keeps 1023 characters, drops the next one and lexes on after it.
        tok.terminated = false;
        tok.end = std::min(n_, q + 1 + kMaxGmshString + 1);
      } else {
        tok.terminated = e != std::string_view::npos;
        tok.end = e == std::string_view::npos ? n_ : e + 1;
      }
    } else if (ident_start(c)) {
      tok.kind = Kind::Ident;
      std::size_t e = q + 1;
      while (e < n_ && ident_char(t_[e])) ++e;
      tok.end = e;
    } else if (is_digit(c) || (c == '.' && q + 1 < n_ && is_digit(t_[q + 1]))) {
      tok.kind = Kind::Number;
      tok.end = number_end(q);
    } else {
      tok.kind = Kind::Op;
      tok.end = q + op_length(q);
    }
    count(tok.end - tok.begin + 1);
    return tok;
  }

  // {digit}+ | {digit}+"."{digit}*{exp}? | {digit}*"."{digit}+{exp}? | {digit}+{exp}
  std::size_t number_end(std::size_t q) const {
    std::size_t e = q;
    while (e < n_ && is_digit(t_[e])) ++e;
    if (e < n_ && t_[e] == '.') {
      ++e;
      while (e < n_ && is_digit(t_[e])) ++e;
    }
    // exp: [Ee][-+]?{digit}+
    if (e < n_ && (t_[e] == 'e' || t_[e] == 'E')) {
      std::size_t x = e + 1;
      if (x < n_ && (t_[x] == '+' || t_[x] == '-')) ++x;
      if (x < n_ && is_digit(t_[x])) {
        while (x < n_ && is_digit(t_[x])) ++x;
        e = x;
      }
    }
    return e;
  }

  std::size_t op_length(std::size_t q) const {
    if (t_.compare(q, 3, "...") == 0) return 3;
    static const char* const two[] = {"+=", "-=", "*=", "/=", "::", "||", "&&", "++",
                                      "--", "==", "!=", "<=", ">=", ">>", "<<"};
    if (q + 1 < n_)
      for (const char* o : two)
        if (t_[q] == o[0] && t_[q + 1] == o[1]) return 2;
    return 1;
  }

  // The token after `end` (comments and blanks skipped), without marking anything.
  Token next(std::size_t end) {
    const std::size_t q = skip_blank(end);
    if (q >= n_) return Token{Kind::End, n_, n_, true};
    return lex(q);
  }

  std::string_view text(const Token& tok) const {
    return t_.substr(tok.begin, tok.end - tok.begin);
  }

  void check_word(const Token& tok) {
    const auto it = words().find(text(tok));
    if (it == words().end()) return;
    const std::string word(text(tok));
    const Word& w = it->second;
    if (w.category == Category::Always) {
      add(tok.begin, word, w.reason);
      return;
    }
    if (w.category == Category::Printf) {
      check_printf(tok);
      return;
    }
    const Token after = next(tok.end);
    if (after.kind == Kind::Op && makes_word_a_name(text(after))) return;
    if (w.category == Category::Command) {
      add(tok.begin, word, w.reason);
      return;
    }
    // Include / Merge: a literal name followed by ';' is followed into that file.
    if (after.kind == Kind::String && after.terminated) {
      const Token semicolon = next(after.end);
      if (semicolon.kind == Kind::Op && text(semicolon) == ";") {
        add(tok.begin, word, "",
            std::string(t_.substr(after.begin + 1, after.end - after.begin - 2)));
        return;
      }
    }
    add(tok.begin, word, w.reason);
  }

  // Printf(...) > "file" / >> "file": a '>' or '>>' outside every bracket before the ';'.
  void check_printf(const Token& tok) {
    int depth = 0;
    std::size_t p = tok.end;
    for (int tokens = 0; tokens < 4096 && !out_of_budget_; ++tokens) {
      const Token t = next(p);
      if (t.kind == Kind::End) return;
      if (t.kind == Kind::Op) {
        const std::string_view op = text(t);
        if (op == ";") return;
        if (op == "(" || op == "[" || op == "{") ++depth;
        if (op == ")" || op == "]" || op == "}") --depth;
        if (depth <= 0 && (op == ">" || op == ">>")) {
          add(tok.begin, "Printf", "writes a file (Printf > file)");
          return;
        }
      }
      p = t.end;
    }
    add(tok.begin, "Printf", "is a statement too long to check for a file it writes");
  }

  static bool is_header(std::string_view w) {
    return w == "For" || w == "Macro" || w == "Function" || w == "Call";
  }

  // The end of flex's piece holding the token that ends at `end`: after the next '\n' or '\r'.
  void queue_piece_end(std::size_t end) {
    const auto it = std::lower_bound(breaks_.begin(), breaks_.end(), end > 0 ? end - 1 : 0);
    const std::size_t p = it == breaks_.end() ? n_ : *it + 1;
    if (!queued_[p]) {
      queued_[p] = 1;
      queue_.push_back(p);
    }
  }

  // A For / Macro / Call header: gmsh saves the file position (fgetpos) when the header is parsed,
  // i.e. the end of the piece holding its last token or the parser's lookahead, and reads on from
  // there (the loop's next pass, the macro's body, the return from a call). Every piece end up to
  // the header's closing bracket or ';' and the token after it is queued.
  void follow_header(const Token& keyword) {
    int depth = 0;
    bool opened = false;
    std::size_t p = keyword.end;
    for (int tokens = 0; tokens < 512 && !out_of_budget_; ++tokens) {
      const Token t = next(p);
      if (t.kind == Kind::End) return;
      queue_piece_end(t.end);
      p = t.end;
      if (t.kind != Kind::Op) continue;
      const std::string_view op = text(t);
      if (op == "(" || op == "[" || op == "{") ++depth, opened = true;
      if (op == ")" || op == "]" || op == "}") --depth;
      if (op == ";" || (opened && depth <= 0)) {
        const Token lookahead = next(p);
        if (lookahead.kind != Kind::End) queue_piece_end(lookahead.end);
        return;
      }
    }
    if (!out_of_budget_)
      add(keyword.begin, std::string(text(keyword)), "starts a header too long to check");
  }

  // Whether [b, e) holds a "*/" that closes a comment opened more than kLongLine bytes before
  // (no "/*" in between; conservative: a "*/" outside any comment counts too).
  bool long_comment_end_line(std::size_t b, std::size_t e) const {
    const std::string_view line = t_.substr(b, e - b);
    for (std::size_t i = line.find("*/"); i != std::string_view::npos; i = line.find("*/", i + 1)) {
      const std::size_t at = b + i;
      if (at > kLongLine &&
          t_.substr(at - kLongLine, kLongLine).find("/*") == std::string_view::npos)
        return true;
    }
    return false;
  }

  void add(std::size_t offset, std::string word, std::string reason, std::string include = {}) {
    if (word.size() > kMaxWord) word = word.substr(0, kMaxWord);
    GeoFinding& f = found_[offset];
    if (!f.command.empty() && f.refused()) return;  // a refusal stands
    f.offset = offset;
    f.command = std::move(word);
    f.reason = std::move(reason);
    f.include = std::move(include);
  }

  std::vector<GeoFinding> finish() {
    std::vector<GeoFinding> out;
    out.reserve(found_.size());
    for (auto& [offset, f] : found_) {
      f.line = line_of(offset);
      out.push_back(std::move(f));
    }
    return out;
  }

  int line_of(std::size_t offset) const {
    if (line_starts_.empty()) {
      int line = 1;
      for (std::size_t i = 0; i < offset && i < n_; ++i) line += t_[i] == '\n';
      return line;
    }
    return static_cast<int>(std::upper_bound(line_starts_.begin(), line_starts_.end(), offset) -
                            line_starts_.begin());
  }

  std::string_view t_;
  std::size_t n_;
  std::vector<uint8_t> visited_, queued_;
  std::size_t word_from_ = 0, word_to_ = 0, suffix_from_ = 0, suffix_end_ = 0;
  std::vector<std::size_t> queue_;
  std::vector<std::size_t> line_starts_, breaks_;  // line starts; '\n' and '\r' positions
  // The first occurrence of a pattern at or after a position, remembered: many runs ask again
  // from inside the same comment. Valid for every `from` in [from_, at_].
  struct NextOf {
    const char* pattern;
    std::size_t from_ = std::string_view::npos, at_ = 0;
    std::size_t next(std::string_view t, std::size_t from) {
      if (from_ != std::string_view::npos && from >= from_ &&
          (at_ == std::string_view::npos || from <= at_))
        return at_;
      from_ = from;
      at_ = t.find(pattern, from);
      return at_;
    }
  };
  NextOf close_{"*/"}, newline_{"\n"};
  std::map<std::size_t, GeoFinding> found_;
  uint64_t steps_ = 0, budget_ = 0;
  bool out_of_budget_ = false;
};

// The first line of a file, as gmsh's MergeFile reads it (fgets, 255 bytes).
std::string first_line(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string head(255, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  const std::size_t nl = head.find('\n');
  return nl == std::string::npos ? head : head.substr(0, nl + 1);
}

constexpr std::uintmax_t kMaxScriptBytes = 256u << 20;
constexpr int kMaxIncludeDepth = 32;
constexpr std::size_t kMaxIncludedFiles = 4096;

// "FILE:LINE[ (included from ...)]: gmsh command 'X' does ...; refused (...)".
std::string refusal(const std::string& path, const std::string& included_from,
                    const GeoFinding& f) {
  const bool word = f.command != "NUL" && f.command != "(script)";
  return path + ":" + std::to_string(f.line) + included_from + ": " +
         (word ? "gmsh command '" + f.command + "' " : "this ") + f.reason +
         "; refused (--allow-geo-commands runs the commands of .geo files, at your own risk)";
}

void check_file(const std::string& path, const std::string& included_from, int depth,
                std::set<std::string>& seen) {
  std::error_code ec;
  const fs::path canonical = fs::weakly_canonical(path, ec);
  if (!seen.insert(ec ? path : canonical.string()).second) return;  // scanned already
  const std::string where = path + included_from;
  if (seen.size() > kMaxIncludedFiles || depth > kMaxIncludeDepth)
    throw InputError(where + ": includes more than " + std::to_string(kMaxIncludedFiles) +
                     " scripts or nests them deeper than " + std::to_string(kMaxIncludeDepth) +
                     "; refused");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (!ec && size > kMaxScriptBytes)
    throw InputError(where + ": a gmsh script of " + std::to_string(size >> 20) +
                     " MiB, more than the 256 MiB bsms checks; refused");
  std::ifstream in(path, std::ios::binary);
  if (!in) return;  // gmsh reports the file it cannot open
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const GeoFinding& f : scan_geo_script(text)) {
    if (f.refused()) throw InputError(refusal(path, included_from, f));
    // gmsh: FixRelativePath(current file, name): relative names are relative to its folder.
    fs::path target(f.include);
    if (target.is_relative()) target = fs::path(path).parent_path() / target;
    const std::string next = target.string();
    // Include parses any file as a script; Merge only what MergeFile would (is_gmsh_script).
    if (!fs::is_regular_file(next, ec) || (f.command != "Include" && !is_gmsh_script(next)))
      continue;
    check_file(next, " (included from " + path + ":" + std::to_string(f.line) + ")", depth + 1,
               seen);
  }
}

}  // namespace

std::vector<GeoFinding> scan_geo_script(std::string_view text) {
  return Scanner(text).run();
}

bool is_gmsh_script(const std::string& path) {
  // gmsh 4.8 Common/OpenFile.cpp MergeFile: these extensions (compared as written) go to readers.
  static const std::set<std::string> readers = {
      ".stl",  ".STL",     ".brep", ".rle",  ".brp",  ".BRP",  ".iges", ".IGES", ".igs",
      ".IGS",  ".step",    ".STEP", ".stp",  ".STP",  ".sat",  ".SAT",  ".x_t",  ".xmt_txt",
      ".x_b",  ".xmt_bin", ".unv",  ".UNV",  ".vtk",  ".VTK",  ".wrl",  ".WRL",  ".vrml",
      ".VRML", ".iv",      ".IV",   ".mesh", ".MESH", ".diff", ".DIFF", ".med",  ".MED",
      ".mmed", ".MMED",    ".rmed", ".RMED", ".bdf",  ".BDF",  ".nas",  ".NAS",  ".dat",
      ".DAT",  ".p3d",     ".P3D",  ".pnm",  ".PNM",  ".pbm",  ".PBM",  ".pgm",  ".PGM",
      ".ppm",  ".PPM",     ".bmp",  ".BMP",  ".jpg",  ".JPG",  ".jpeg", ".JPEG", ".png",
      ".PNG",  ".ply2",    ".PLY2", ".ply",  ".PLY",  ".geom", ".GEOM", ".cgns", ".CGNS",
      ".pch"};
  if (readers.count(fs::path(path).extension().string())) return false;
  const std::string head = first_line(path);
  for (const char* h :
       {"$PTS", "$NO", "$PARA", "$ELM", "$MeshFormat", "$Comments", "$PostFormat", "$View"})
    if (head.compare(0, std::strlen(h), h) == 0) return false;
  return true;
}

void check_geo_script(const std::string& path) {
  std::set<std::string> seen;
  check_file(path, "", 0, seen);
}

}  // namespace bsms
