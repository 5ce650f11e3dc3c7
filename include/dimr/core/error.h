// Error types shared by every layer (core layer, no dependencies). Messages always name what
// failed and where (file, field, line, frame) so that a user can act on them.
#pragma once

#include <stdexcept>
#include <string>

namespace dimr {

// Base class of every error dimr throws on bad input or bad state.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// A file or byte stream could not be parsed (malformed, truncated, wrong counts).
class ParseError : public Error {
 public:
  ParseError(const std::string& source, const std::string& problem)
      : Error(source + ": " + problem), source_(source), problem_(problem) {}
  const std::string& source() const { return source_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string source_;
  std::string problem_;
};

// An argument or configuration value is out of its valid range.
class InvalidArgument : public Error {
 public:
  explicit InvalidArgument(const std::string& what) : Error(what) {}
};

}  // namespace dimr
