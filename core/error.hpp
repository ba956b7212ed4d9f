// Typed errors with context. The CLI maps InputError to one line on stderr and exit code 2,
// NumericalError (a solver step that failed) to exit code 3, IoError to 4, DistributedError to 5.
#pragma once

#include <stdexcept>
#include <string>

namespace bsms {

// Bad input: a missing or malformed file, an unknown key, an impossible parameter, NaN data.
// The message must name the file, key or value and say what is expected.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

// A numerical failure during a computation (NaN, inverted element, particle outside the mesh).
// The message names the step, the particle (or node) and the cause.
class NumericalError : public std::runtime_error {
 public:
  explicit NumericalError(const std::string& what) : std::runtime_error(what) {}
};

// An I/O failure that is not the user's fault in the input (e.g. disk full while writing).
class IoError : public std::runtime_error {
 public:
  explicit IoError(const std::string& what) : std::runtime_error(what) {}
};

// Distributed training lost a rank: one that died, hung past the timeout or closed its connection.
// The message names this rank, the step and what was lost; the last checkpoint stays intact.
class DistributedError : public std::runtime_error {
 public:
  explicit DistributedError(const std::string& what) : std::runtime_error(what) {}
};

// Exit with `code` without a message: the cause was already reported in one line by another
// process (a rank of the same distributed run).
class SilentExit : public std::runtime_error {
 public:
  explicit SilentExit(int code) : std::runtime_error("exit " + std::to_string(code)), code(code) {}
  int code;
};

}  // namespace bsms
