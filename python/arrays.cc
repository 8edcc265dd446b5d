#include "python/arrays.h"

#include <cmath>
#include <stdexcept>

namespace echoservo::python {

namespace {

// A float64 copy of `value` (any real or integer dtype, or a sequence of numbers); ValueError
// naming `name` for anything else.
py::array_t<double> AsFloat64(const py::handle& value, const std::string& name) {
  if (value.is_none()) throw py::value_error(name + ": expected numbers, got None");
  py::array a;
  try {
    a = py::array::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!a) throw py::value_error(name + ": expected an array or a sequence of numbers");
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::value_error(name + ": expected real numbers, got dtype " +
                          py::str(a.dtype()).cast<std::string>());
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
}

void CheckFinite(const double* data, std::size_t n, const std::string& name) {
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(data[i]))
      throw py::value_error(name + ": element " + std::to_string(i) + " is not finite (" +
                            std::to_string(data[i]) + ")");
}

}  // namespace

std::vector<double> FiniteVector(const py::handle& value, const std::string& name,
                                 std::size_t min_size) {
  const py::array_t<double> a = AsFloat64(value, name);
  if (a.ndim() != 1)
    throw py::value_error(name + ": expected a 1-D array, got " + std::to_string(a.ndim()) + "-D");
  const auto n = static_cast<std::size_t>(a.shape(0));
  if (n < min_size)
    throw py::value_error(name + ": expected at least " + std::to_string(min_size) +
                          " values, got " + std::to_string(n));
  CheckFinite(a.data(), n, name);
  return std::vector<double>(a.data(), a.data() + n);
}

Eigen::Vector3d Vec3(const py::handle& value, const std::string& name) {
  const std::vector<double> v = FiniteVector(value, name);
  if (v.size() != 3)
    throw py::value_error(name + ": expected 3 numbers (x, y, z), got " + std::to_string(v.size()));
  return {v[0], v[1], v[2]};
}

Eigen::MatrixXd FiniteMatrix(const py::handle& value, const std::string& name, int rows, int cols) {
  const py::array_t<double> a = AsFloat64(value, name);
  if (a.ndim() != 2 || a.shape(0) != rows || a.shape(1) != cols)
    throw py::value_error(name + ": expected shape (" + std::to_string(rows) + ", " +
                          std::to_string(cols) + ")");
  CheckFinite(a.data(), static_cast<std::size_t>(rows * cols), name);
  Eigen::MatrixXd m(rows, cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) m(r, c) = a.at(r, c);
  return m;
}

Eigen::Isometry3d RigidTransform(const py::handle& value, const std::string& name) {
  const Eigen::MatrixXd m = FiniteMatrix(value, name, 4, 4);
  if (m.row(3).transpose() != Eigen::Vector4d(0, 0, 0, 1))
    throw py::value_error(name + ": the bottom row must be 0 0 0 1");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
      r.determinant() < 0)
    throw py::value_error(name + ": the upper-left 3x3 is not a rotation (within 1e-6)");
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = m.topRightCorner<3, 1>();
  return t;
}

py::array_t<double> ToArray(const Eigen::Vector3d& v) {
  py::array_t<double> a(3);
  for (int i = 0; i < 3; ++i) a.mutable_at(i) = v[i];
  return a;
}

py::array_t<double> ToArray(const Eigen::MatrixXd& m) {
  py::array_t<double> a({m.rows(), m.cols()});
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c) a.mutable_at(r, c) = m(r, c);
  return a;
}

py::array_t<double> ToArray(const Eigen::Isometry3d& t) {
  return ToArray(Eigen::MatrixXd(t.matrix()));
}

py::array_t<double> ToArray(const std::vector<double>& v) {
  py::array_t<double> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::array_t<double> ToArray(const std::vector<Eigen::Vector3d>& points) {
  py::array_t<double> a({static_cast<py::ssize_t>(points.size()), py::ssize_t{3}});
  double* out = a.mutable_data();
  for (const Eigen::Vector3d& p : points)
    for (int i = 0; i < 3; ++i) *out++ = p[i];
  return a;
}

py::object FromJson(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

}  // namespace echoservo::python
