// A compiled arithmetic expression over named inputs, for effects a user writes in a file
// (hw/effect_file.h) rather than in C++.
//
// The text is muParser syntax: + - * / ^, comparisons, `c ? a : b`, and the functions
// sin cos tan asin acos atan sinh cosh tanh exp log ln log10 log2 sqrt abs sign rint min
// max sum avg. Variables are the names given at construction, in that order (Evaluate takes
// their values in the same order); named constants are fixed numbers (e.g. pi). Units are
// whatever the caller's names say (the project's convention: the unit is in the name).
// The expression is parsed once; Evaluate runs its byte code (tens of ns). An instance is
// not thread-safe (Evaluate writes the instance's input slots): give each thread its own
// copy (copying re-parses the text).
#pragma once

#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace echoservo::hw {

// A syntax error, unknown variable or function, or bad name; the message gives the
// character position (0-based) and the reason.
class ExpressionError : public std::invalid_argument {
 public:
  ExpressionError(const std::string& message, int position)
      : std::invalid_argument(message), position_(position) {}
  int position() const { return position_; }  // 0-based character, -1 when unknown

 private:
  int position_;
};

class Expression {
 public:
  // Throws ExpressionError for an empty text, a syntax error, an unknown variable or
  // function, or an invalid or duplicate variable or constant name.
  Expression(std::string text, std::vector<std::string> variables,
             std::vector<std::pair<std::string, double>> constants = {});
  Expression(const Expression& other);
  Expression& operator=(const Expression& other);
  Expression(Expression&&) noexcept;
  Expression& operator=(Expression&&) noexcept;
  ~Expression();

  const std::string& text() const { return text_; }
  const std::vector<std::string>& variables() const { return variables_; }
  // `values` holds one value per variable, in variables() order.
  double Evaluate(const double* values) const;
  // Zero-copy form: write the inputs into Inputs() (variables() order), then Evaluate().
  std::span<double> Inputs() const;
  double Evaluate() const;
  // The variables the text uses, in variables() order.
  std::vector<std::string> UsedVariables() const;

 private:
  struct Impl;
  std::string text_;
  std::vector<std::string> variables_;
  std::vector<std::pair<std::string, double>> constants_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace echoservo::hw
