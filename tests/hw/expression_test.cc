// hw::Expression: muParser behind a small interface. Values are checked against the same
// arithmetic in C++ (exact for single operations, 1e-15 relative for library functions);
// errors must give the position and the reason.
#include "hw/expression.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;

std::string ErrorOf(const std::string& text, const std::vector<std::string>& vars, int* pos) {
  try {
    Expression e(text, vars, {{"pi", std::numbers::pi}});
  } catch (const ExpressionError& x) {
    *pos = x.position();
    return x.what();
  }
  ADD_FAILURE() << "'" << text << "' parsed";
  return "";
}

TEST(Expression, EvaluatesVariablesInOrderAndConstants) {
  const Expression e("a_n*exp(-((base_mm-x0_mm)/w_mm)^2) + 0*pi",
                     {"a_n", "x0_mm", "w_mm", "base_mm"}, {{"pi", std::numbers::pi}});
  const double v[] = {0.3, 2.0, 0.5, 2.25};
  EXPECT_NEAR(e.Evaluate(v), 0.3 * std::exp(-0.25), 1e-15);
  const Expression c("2*pi", {}, {{"pi", std::numbers::pi}});
  EXPECT_EQ(c.Evaluate(nullptr), 2.0 * std::numbers::pi);
  const Expression m("b*speed_mm_s", {"b", "speed_mm_s"});
  const double w[] = {0.006, 37.5};
  EXPECT_EQ(m.Evaluate(w), 0.006 * 37.5);  // one multiplication: exact
}

TEST(Expression, InputSlotsAndCopiesAreIndependent) {
  const Expression a("x*x+y", {"x", "y"});
  Expression b = a;
  a.Inputs()[0] = 3.0;
  a.Inputs()[1] = 1.0;
  b.Inputs()[0] = 2.0;
  b.Inputs()[1] = 0.0;
  EXPECT_EQ(a.Evaluate(), 10.0);
  EXPECT_EQ(b.Evaluate(), 4.0);
  const Expression moved = std::move(b);
  EXPECT_EQ(moved.Evaluate(), 4.0);
}

TEST(Expression, ReportsUsedVariablesInDeclaredOrder) {
  const Expression e("c*speed_mm_s + 0*time_s", {"c", "unused", "speed_mm_s", "time_s"});
  EXPECT_EQ(e.UsedVariables(), (std::vector<std::string>{"c", "speed_mm_s", "time_s"}));
}

TEST(Expression, SyntaxErrorGivesPosition) {
  int pos = -2;
  const std::string m = ErrorOf("a*(b+", {"a", "b"}, &pos);
  EXPECT_GE(pos, 4);
  ExpectContains(m, "position");
}

TEST(Expression, UnknownVariableIsNamedWithItsPositionAndTheAvailableOnes) {
  int pos = -2;
  const std::string m = ErrorOf("a*speed", {"a", "speed_mm_s"}, &pos);
  EXPECT_EQ(pos, 2);
  ExpectContains(m, "unknown variable 'speed'");
  ExpectContains(m, "position 2");
  ExpectContains(m, "speed_mm_s");
}

TEST(Expression, UnknownFunctionIsNamed) {
  int pos = -2;
  const std::string m = ErrorOf("1 + tanhh (a)", {"a"}, &pos);
  EXPECT_EQ(pos, 4);
  ExpectContains(m, "unknown function 'tanhh'");
}

TEST(Expression, EmptyTextAndBadNamesAreRejected) {
  int pos = 0;
  ExpectContains(ErrorOf("  ", {"a"}, &pos), "empty");
  ExpectContains(ErrorOf("a", {"a", "a"}, &pos), "twice");
  ExpectContains(ErrorOf("a", {"pi"}, &pos), "name of a variable");
  ExpectContains(ErrorOf("a", {"a-b"}, &pos), "invalid variable 'a-b'");
}

}  // namespace
}  // namespace echoservo::hw
