// The Python module's conversions between numpy and the libraries' types (every binding
// uses them): a bad argument is refused with a ValueError that names it and says why (dtype,
// shape, layout, a value that is not finite). Vectors and matrices are float64 arrays in the
// libraries' units (mm, s, rad); point arrays are (n, 3).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <vector>

namespace echoservo::python {

namespace py = pybind11;

// A 1-D array (or sequence) of finite numbers, as float64, of at least `min_size` entries.
// Any real dtype is converted (a column of a 2-D table too: a strided view is copied).
std::vector<double> FiniteVector(const py::handle& value, const std::string& name,
                                 std::size_t min_size = 0);
// Exactly 3 finite numbers.
Eigen::Vector3d Vec3(const py::handle& value, const std::string& name);
// A (rows, cols) array of finite numbers.
Eigen::MatrixXd FiniteMatrix(const py::handle& value, const std::string& name, int rows, int cols);
// A 4×4 rigid transform (mm), bottom row 0 0 0 1, rotation orthonormal within 1e-6.
Eigen::Isometry3d RigidTransform(const py::handle& value, const std::string& name);

py::array_t<double> ToArray(const Eigen::Vector3d& v);
py::array_t<double> ToArray(const Eigen::MatrixXd& m);
py::array_t<double> ToArray(const Eigen::Isometry3d& t);  // 4×4
py::array_t<double> ToArray(const std::vector<double>& v);
py::array_t<double> ToArray(const std::vector<Eigen::Vector3d>& points);  // (n, 3)

// A JSON text as Python objects (json.loads): the same keys and values the command line
// prints.
py::object FromJson(const std::string& text);

// Module registration, one per bindings file.
void RegisterVolumes(py::module_& m);
void RegisterDetector(py::module_& m);
void RegisterMotion(py::module_& m);
void RegisterRuns(py::module_& m);
void RegisterCommands(py::module_& m);
void RegisterLab(py::module_& m);
void RegisterBench(py::module_& m);
void RegisterIgtl(py::module_& m);

}  // namespace echoservo::python
