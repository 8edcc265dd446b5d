#include "hw/expression.h"

#include <muParser.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <cstddef>

namespace echoservo::hw {

struct Expression::Impl {
  mu::Parser parser;
  std::vector<double> slots;  // one per variable; muParser reads them by address
};

namespace {

std::string Describe(const mu::Parser::exception_type& e, const std::string& text,
                     const std::vector<std::string>& variables) {
  const std::string token = e.GetToken();
  const int pos = e.GetPos();
  if (e.GetCode() == mu::ecUNASSIGNABLE_TOKEN && !token.empty()) {
    // An identifier muParser does not know: a function when '(' follows it.
    std::size_t after = pos >= 0 ? static_cast<std::size_t>(pos) + token.size() : text.size();
    while (after < text.size() && std::isspace(static_cast<unsigned char>(text[after]))) ++after;
    if (after < text.size() && text[after] == '(') {
      return "unknown function '" + token + "' at position " + std::to_string(pos) +
             " (known: sin cos tan asin acos atan sinh cosh tanh exp log ln log10 log2 sqrt abs "
             "sign rint min max sum avg)";
    }
    std::string known;
    for (const std::string& v : variables) known += (known.empty() ? "" : ", ") + v;
    return "unknown variable '" + token + "' at position " + std::to_string(pos) +
           " (available: " + (known.empty() ? "none" : known) + ")";
  }
  std::string message = e.GetMsg();
  if (pos >= 0 && message.find("position") == std::string::npos)
    message += " (at position " + std::to_string(pos) + ")";
  return message;
}

}  // namespace

Expression::Expression(std::string text, std::vector<std::string> variables,
                       std::vector<std::pair<std::string, double>> constants)
    : text_(std::move(text)),
      variables_(std::move(variables)),
      constants_(std::move(constants)),
      impl_(std::make_unique<Impl>()) {
  if (std::all_of(text_.begin(), text_.end(),
                  [](unsigned char c) { return std::isspace(c) != 0; })) {
    throw ExpressionError("empty expression", 0);
  }
  impl_->slots.assign(variables_.size(), 0.0);
  std::string defining;
  try {
    for (std::size_t i = 0; i < variables_.size(); ++i) {
      defining = "variable '" + variables_[i] + "'";
      if (std::count(variables_.begin(), variables_.end(), variables_[i]) > 1)
        throw ExpressionError("variable '" + variables_[i] + "' given twice", -1);
      impl_->parser.DefineVar(variables_[i], &impl_->slots[i]);
    }
    for (const auto& [name, value] : constants_) {
      defining = "constant '" + name + "'";
      if (std::find(variables_.begin(), variables_.end(), name) != variables_.end())
        throw ExpressionError("constant '" + name + "' has the name of a variable", -1);
      impl_->parser.DefineConst(name, value);
    }
  } catch (const mu::Parser::exception_type& e) {
    throw ExpressionError("invalid " + defining + ": " + e.GetMsg(), -1);
  }
  try {
    impl_->parser.SetExpr(text_);
    impl_->parser.Eval();  // parses now: errors surface here, not at the first real use
  } catch (const mu::Parser::exception_type& e) {
    throw ExpressionError(Describe(e, text_, variables_), e.GetPos());
  }
}

Expression::Expression(const Expression& other)
    : Expression(other.text_, other.variables_, other.constants_) {}

Expression& Expression::operator=(const Expression& other) {
  if (this != &other) *this = Expression(other);
  return *this;
}

Expression::Expression(Expression&&) noexcept = default;
Expression& Expression::operator=(Expression&&) noexcept = default;
Expression::~Expression() = default;

double Expression::Evaluate(const double* values) const {
  std::copy(values, values + impl_->slots.size(), impl_->slots.begin());
  return impl_->parser.Eval();
}

std::span<double> Expression::Inputs() const { return impl_->slots; }

double Expression::Evaluate() const { return impl_->parser.Eval(); }

std::vector<std::string> Expression::UsedVariables() const {
  // GetUsedVar re-parses the expression; a copy keeps this instance's byte code.
  mu::Parser probe;
  std::vector<double> slots(variables_.size(), 0.0);
  for (std::size_t i = 0; i < variables_.size(); ++i) probe.DefineVar(variables_[i], &slots[i]);
  for (const auto& [name, value] : constants_) probe.DefineConst(name, value);
  probe.SetExpr(text_);
  const mu::varmap_type& used = probe.GetUsedVar();
  std::vector<std::string> out;
  for (const std::string& v : variables_) {
    if (used.count(v) != 0) out.push_back(v);
  }
  return out;
}

}  // namespace echoservo::hw
