// The check bsms runs on a gmsh script (.geo, gmsh 4.8's language) before gmsh runs it: commands
// that run a program, end the process, write files or read other scripts are refused, with the
// file, the line and the command. gmsh's language is case-sensitive, skips // and /* */ comments
// and '...' / "..." strings (no escapes); the check reads the text as gmsh's lexer does.
//
// gmsh does not read a script in one pass: a For loop or a Macro body is read again from the end
// of the lexer's piece (a line, or part of a long one) that held its header, a false If branch
// (and a For loop run zero times) is skipped by a search for its EndIf / Else / ElseIf / EndFor /
// Return that ignores strings, and a string longer than 1023 characters is cut there, the rest
// read as code. Text that one pass reads as a string or a comment can be code for another. The
// scan therefore lexes the text from every place gmsh can resume: the start, the piece ends after
// every For / Macro / Call header, after every EndIf / EndFor / Return / Else and before every
// ElseIf (wherever they occur, strings and comments included), and every position of a line long
// enough to be read in pieces; it cuts strings as gmsh does and refuses NUL bytes. The worker that
// runs gmsh (gmsh_worker.hpp) also forbids running programs and writing files at the kernel where
// it can (seccomp), so a command the scan missed still could not run one.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace bsms {

struct GeoFinding {
  std::size_t offset = 0;  // byte offset of the command in the text
  int line = 0;            // its line (1-based, as gmsh counts: '\n')
  std::string command;     // the word (at most 64 characters)
  std::string reason;      // why it is refused; empty for an include to follow
  std::string include;     // Include / Merge of a literal file name: that name, else empty
  bool refused() const { return !reason.empty(); }
};

// The findings of one script's text, ordered by offset (each offset once). Pure: reads no file.
// Linear in the text's length (a step budget refuses pathological texts rather than hang).
std::vector<GeoFinding> scan_geo_script(std::string_view text);

// Whether gmsh 4.8 reads `path` as a script when it opens or merges it (MergeFile's rules: not a
// known mesh or CAD extension, and a first line that is not an MSH or POS header).
bool is_gmsh_script(const std::string& path);

// Scans `path` (a script) and the scripts it includes or merges by a literal name, relative to
// the including file as gmsh resolves them; throws InputError for the first refused command:
// "FILE:LINE: gmsh command 'X' ...; refused (...)" naming where an included file was included.
void check_geo_script(const std::string& path);

}  // namespace bsms
