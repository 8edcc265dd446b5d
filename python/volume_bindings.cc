// Volumes (imaging/volume.h) and their files (imaging/io/volume_io.h), PLUS sequences
// (imaging/io/plus_sequence.h) in Python. Voxel arrays are (nz, ny, nx) uint8, x fastest as
// in the files, and are views of the C++ memory (no copy) kept alive by their owner.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "imaging/io/volume_io.h"
#include "imaging/volume.h"
#include "python/arrays.h"

namespace echoservo::python {

namespace {

using imaging::PlusSequence;
using imaging::Volume;
using VolumePtr = std::shared_ptr<Volume>;
using SequencePtr = std::shared_ptr<PlusSequence>;

// A (nz, ny, nx) uint8 view of `data`, owned by `owner`.
py::array_t<std::uint8_t> VoxelView(std::uint8_t* data, const std::array<py::ssize_t, 3>& zyx,
                                    py::handle owner) {
  const py::ssize_t nx = zyx[2], ny = zyx[1];
  return py::array_t<std::uint8_t>({zyx[0], zyx[1], zyx[2]}, {nx * ny, nx, py::ssize_t{1}}, data,
                                   owner);
}

// The voxel array a Volume is made from: C-contiguous uint8 (nz, ny, nx). A transposed or
// sliced array is not C-contiguous, and would put x where z is expected: refused, not copied.
py::array_t<std::uint8_t> CheckVoxels(const py::handle& value, const std::string& name) {
  py::array a;
  try {
    a = py::array::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!a) throw py::value_error(name + ": expected a numpy uint8 array of shape (nz, ny, nx)");
  if (a.dtype().kind() != 'u' || a.itemsize() != 1)
    throw py::value_error(name + ": expected dtype uint8 (display values 0-255), got " +
                          py::str(a.dtype()).cast<std::string>() +
                          "; convert explicitly, e.g. np.clip(x, 0, 255).astype(np.uint8)");
  if (a.ndim() != 3)
    throw py::value_error(name + ": expected 3 dimensions (nz, ny, nx), got " +
                          std::to_string(a.ndim()));
  if (!(a.flags() & py::array::c_style))
    throw py::value_error(name +
                          ": expected a C-contiguous array (x fastest); a transposed or sliced "
                          "array would be read in the wrong order: pass np.ascontiguousarray(" +
                          name + ") if its axes are (z, y, x)");
  return py::reinterpret_borrow<py::array_t<std::uint8_t>>(a);
}

VolumePtr MakeVolume(const py::handle& voxels, const py::handle& spacing_mm,
                     const py::handle& origin_mm, const py::handle& direction) {
  const py::array_t<std::uint8_t> a = CheckVoxels(voxels, "voxels");
  imaging::VolumeGeometry g;
  for (int i = 0; i < 3; ++i) {
    const py::ssize_t n = a.shape(2 - i);
    if (n > imaging::VolumeGeometry::kMaxDim)
      throw py::value_error("voxels: " + std::to_string(n) + " voxels along an axis (at most " +
                            std::to_string(imaging::VolumeGeometry::kMaxDim) + ")");
    g.dims[i] = static_cast<int>(n);
  }
  g.spacing_mm = Vec3(spacing_mm, "spacing_mm");
  g.origin_mm = Vec3(origin_mm, "origin_mm");
  if (!direction.is_none()) g.direction = FiniteMatrix(direction, "direction", 3, 3);
  auto v = std::make_shared<Volume>(Volume::Create(g));  // validates (ValueError naming it)
  std::memcpy(v->voxels().data(), a.data(), v->voxel_count());
  return v;
}

py::object OptionalTransform(bool known, const Eigen::Isometry3d& t) {
  return known ? py::object(ToArray(t)) : py::object(py::none());
}

// The numpy dtype of a MetaImage element type.
py::dtype ElementDtype(const PlusSequence& s) {
  const std::string& t = s.element_type;
  if (t == "MET_UCHAR") return py::dtype::of<std::uint8_t>();
  if (t == "MET_CHAR") return py::dtype::of<std::int8_t>();
  if (t == "MET_USHORT") return py::dtype::of<std::uint16_t>();
  if (t == "MET_SHORT") return py::dtype::of<std::int16_t>();
  if (t == "MET_UINT") return py::dtype::of<std::uint32_t>();
  if (t == "MET_INT") return py::dtype::of<std::int32_t>();
  if (t == "MET_FLOAT") return py::dtype::of<float>();
  if (t == "MET_DOUBLE") return py::dtype::of<double>();
  throw py::value_error("pixels: element type " + t + " has no numpy equivalent here");
}

void BindVolume(py::module_& m) {
  py::class_<Volume, VolumePtr>(
      m, "Volume",
      "One 3D ultrasound volume: uint8 voxels on a regular grid placed in the image frame (mm).\n"
      "voxels is a (nz, ny, nx) view of the volume's own memory (x fastest, as in MetaImage);\n"
      "physical_mm = origin_mm + direction @ (index * spacing_mm) with index = (i, j, k).")
      .def(py::init(&MakeVolume), py::arg("voxels"),
           py::arg("spacing_mm") = py::make_tuple(1, 1, 1),
           py::arg("origin_mm") = py::make_tuple(0, 0, 0), py::arg("direction") = py::none(),
           "A volume from a C-contiguous uint8 array of shape (nz, ny, nx) (copied), its voxel\n"
           "spacing (mm, along x, y, z), the centre of voxel (0, 0, 0) (mm) and the 3x3 direction\n"
           "matrix (columns: the index axes; identity by default). ValueError naming the\n"
           "argument for a wrong dtype, shape or layout, or a spacing that is not positive.")
      .def_property_readonly(
          "voxels",
          [](py::object self) {
            Volume& v = self.cast<Volume&>();
            return VoxelView(v.voxels().data(), {v.dims().z(), v.dims().y(), v.dims().x()}, self);
          },
          "(nz, ny, nx) uint8 view of the voxels (writable; no copy)")
      .def_property_readonly(
          "dims",
          [](const Volume& v) { return py::make_tuple(v.dims().x(), v.dims().y(), v.dims().z()); },
          "voxel counts (nx, ny, nz)")
      .def_property_readonly(
          "spacing_mm", [](const Volume& v) { return ToArray(v.spacing_mm()); },
          "voxel pitch along x, y, z (mm)")
      .def_property_readonly(
          "origin_mm", [](const Volume& v) { return ToArray(v.origin_mm()); },
          "centre of voxel (0, 0, 0) in the image frame (mm)")
      .def_property_readonly(
          "direction", [](const Volume& v) { return ToArray(Eigen::MatrixXd(v.direction())); },
          "3x3: columns are the index axes in the image frame")
      .def_property(
          "image_to_probe",
          [](const Volume& v) {
            return OptionalTransform(v.has_image_to_probe(), v.image_to_probe());
          },
          [](Volume& v, const py::handle& t) {
            v.set_image_to_probe(RigidTransform(t, "image_to_probe"));
          },
          "ImageToProbe 4x4 rigid transform (mm), or None when the scanning geometry is unknown")
      .def_property(
          "probe_to_reference", [](const Volume& v) { return ToArray(v.probe_to_reference()); },
          [](Volume& v, const py::handle& t) {
            v.set_probe_to_reference(RigidTransform(t, "probe_to_reference"));
          },
          "ProbeToReference 4x4 rigid transform (mm)")
      .def_property("timestamp_s", &Volume::timestamp_s, &Volume::set_timestamp_s,
                    "acquisition time (s, the stream's clock)")
      .def_property("frame_index", &Volume::frame_index, &Volume::set_frame_index,
                    "frame number in its stream")
      .def(
          "index_to_physical",
          [](const Volume& v, const py::handle& ijk) {
            return ToArray(v.IndexToPhysical(Vec3(ijk, "index")));
          },
          py::arg("index"), "continuous voxel index (i, j, k) -> image-frame point (mm)")
      .def(
          "physical_to_index",
          [](const Volume& v, const py::handle& p) {
            return ToArray(v.PhysicalToIndex(Vec3(p, "physical_mm")));
          },
          py::arg("physical_mm"), "image-frame point (mm) -> continuous voxel index (i, j, k)")
      .def(
          "sample",
          [](const Volume& v, const py::handle& p) { return v.Sample(Vec3(p, "physical_mm")); },
          py::arg("physical_mm"),
          "trilinear value at an image-frame point (mm); NaN outside the voxel centres' box")
      .def("__repr__", [](const Volume& v) {
        return "<echoservo.Volume " + std::to_string(v.dims().x()) + "x" +
               std::to_string(v.dims().y()) + "x" + std::to_string(v.dims().z()) + ", spacing " +
               py::str(ToArray(v.spacing_mm())).cast<std::string>() + " mm>";
      });

  m.def(
      "read_volume",
      [](const std::filesystem::path& p) {
        return std::make_shared<Volume>(imaging::ReadVolume(p));
      },
      py::arg("path"), py::call_guard<py::gil_scoped_release>(),
      "Read a volume file: MetaImage (.mha, .mhd), VTK XML image data (.vti) or NRRD (.nrrd,\n"
      ".nhdr); uint8 single-component data. Poses and time are not in these files (identity,\n"
      "0). ValueError naming the file and the problem.");
  m.def(
      "write_volume",
      [](const Volume& v, const std::filesystem::path& p, bool compress) {
        imaging::WriteVolume(v, p, {compress});
      },
      py::arg("volume"), py::arg("path"), py::arg("compress") = true,
      py::call_guard<py::gil_scoped_release>(),
      "Write a volume: .mha, .mhd (+ .raw/.zraw) or .vti by extension; zlib when compress.");
}

// IndexError unless `i` is one of the sequence's frames.
void CheckFrame(const PlusSequence& s, std::size_t i) {
  if (i >= s.frames.size())
    throw py::index_error("frame " + std::to_string(i) + " of " + std::to_string(s.frames.size()));
}

py::dict FrameFields(const PlusSequence& s, std::size_t i) {
  CheckFrame(s, i);
  py::dict d;
  for (const auto& [k, v] : s.frames[i].fields) d[py::str(k)] = v;
  return d;
}

void BindSequence(py::module_& m) {
  py::class_<PlusSequence, SequencePtr>(
      m, "Sequence",
      "A PLUS sequence metafile (.igs.mha, .igs.nrrd): tracked frames (2D or 3D) with per-frame\n"
      "fields (transforms, statuses, timestamps). pixels is a (frames, nz, ny, nx) view of its\n"
      "memory (no copy).")
      .def_property_readonly(
          "frame_count", [](const PlusSequence& s) { return s.frames.size(); }, "number of frames")
      .def("__len__", [](const PlusSequence& s) { return s.frames.size(); })
      .def_property_readonly(
          "frame_dims",
          [](const PlusSequence& s) {
            return py::make_tuple(s.frame_dims[0], s.frame_dims[1], s.frame_dims[2]);
          },
          "pixels per frame (nx, ny, nz); nz = 1 for 2D frames")
      .def_property_readonly(
          "element_type", [](const PlusSequence& s) { return s.element_type; },
          "MetaImage element type of the pixels (MET_UCHAR, ...; MET_OTHER without pixels)")
      .def_property_readonly(
          "spacing_mm", [](const PlusSequence& s) { return ToArray(s.spacing_mm); },
          "pixel pitch along x, y, z of one frame (mm)")
      .def_property_readonly(
          "origin_mm", [](const PlusSequence& s) { return ToArray(s.origin_mm); },
          "centre of pixel (0, 0, 0) of a frame, in its image frame (mm)")
      .def_property_readonly(
          "direction", [](const PlusSequence& s) { return ToArray(Eigen::MatrixXd(s.direction)); },
          "3x3: columns are the index axes in the image frame")
      .def_property_readonly(
          "header_fields",
          [](const PlusSequence& s) {
            py::dict d;
            for (const auto& [k, v] : s.header_fields) d[py::str(k)] = v;
            return d;
          },
          "header fields other than the geometry (e.g. UltrasoundImageOrientation)")
      .def_property_readonly("field_names", &PlusSequence::FrameFieldNames,
                             "names of the per-frame fields (union over frames), sorted")
      .def_property_readonly(
          "pixels",
          [](py::object self) -> py::object {
            PlusSequence& s = self.cast<PlusSequence&>();
            if (s.FrameBytes() == 0) return py::none();
            const py::dtype dt = ElementDtype(s);
            const auto n = static_cast<py::ssize_t>(s.frames.size());
            const py::ssize_t nx = s.frame_dims[0], ny = s.frame_dims[1], nz = s.frame_dims[2];
            const py::ssize_t e = s.element_size;
            return py::array(dt, {n, nz, ny, nx}, {nx * ny * nz * e, nx * ny * e, nx * e, e},
                             s.pixels.data(), self);
          },
          "(frames, nz, ny, nx) view of the pixels (None for a tracker-only sequence)")
      .def("frame_fields", &FrameFields, py::arg("frame"),
           "the frame's fields as a dict of strings")
      .def_property_readonly(
          "timestamps_s",
          [](const PlusSequence& s) {
            std::vector<double> t;
            for (const auto& f : s.frames)
              t.push_back(f.Timestamp().value_or(std::numeric_limits<double>::quiet_NaN()));
            return ToArray(t);
          },
          "each frame's Timestamp (else UnfilteredTimestamp), s; NaN where absent")
      .def(
          "transforms",
          [](const PlusSequence& s, const std::string& name) {
            const auto n = static_cast<py::ssize_t>(s.frames.size());
            py::array_t<double> a({n, py::ssize_t{4}, py::ssize_t{4}});
            double* out = a.mutable_data();
            for (const auto& f : s.frames) {
              const auto t = f.TransformValid(name) ? f.Transform(name) : std::nullopt;
              for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c)
                  *out++ = t ? (*t)(r, c) : std::numeric_limits<double>::quiet_NaN();
            }
            return a;
          },
          py::arg("name"),
          "a transform of every frame, (frames, 4, 4) in mm, e.g. 'ProbeToTracker' (with or\n"
          "without the Transform suffix); NaN for a frame where it is absent or its status is\n"
          "not OK")
      .def(
          "write",
          [](const PlusSequence& s, const std::filesystem::path& p, bool compress) {
            imaging::WritePlusSequence(s, p, compress);
          },
          py::arg("path"), py::arg("compress") = true, py::call_guard<py::gil_scoped_release>(),
          "Write this sequence (its pixels as they are now: `pixels` is writable, and its\n"
          "fields) to .igs.mha (or .igs.nrrd), zlib/gzip when compress.")
      .def(
          "volume",
          [](const PlusSequence& s, std::size_t i) {
            CheckFrame(s, i);
            return std::make_shared<Volume>(imaging::SequenceFrameToVolume(s, i));
          },
          py::arg("frame"),
          "frame `frame` as a Volume (uint8 only; a copy): geometry, time, ImageToProbe and\n"
          "ProbeToReference from the frame's fields");

  m.def(
      "read_sequence",
      [](const std::filesystem::path& p) {
        return std::make_shared<PlusSequence>(imaging::ReadPlusSequence(p));
      },
      py::arg("path"), py::call_guard<py::gil_scoped_release>(),
      "Read a PLUS sequence metafile (.igs.mha, .igs.nrrd, tracker-only ones too), pixels\n"
      "included. ValueError naming the file and the problem.");
  m.def(
      "write_sequence",
      [](const std::vector<VolumePtr>& volumes, const std::filesystem::path& p, bool compress) {
        if (volumes.empty()) throw py::value_error("volumes: at least one volume is needed");
        std::vector<Volume> copies;
        copies.reserve(volumes.size());
        for (std::size_t i = 0; i < volumes.size(); ++i) {
          if (!volumes[i]) throw py::value_error("volumes[" + std::to_string(i) + "]: None");
          copies.push_back(*volumes[i]);
        }
        py::gil_scoped_release release;
        imaging::WritePlusSequence(imaging::VolumesToSequence(copies), p, compress);
      },
      py::arg("volumes"), py::arg("path"), py::arg("compress") = true,
      "Write volumes of equal geometry as a PLUS sequence (.igs.mha, or .igs.nrrd) with each\n"
      "one's Timestamp, FrameNumber, ImageToProbe and ProbeToReference transforms.");
}

}  // namespace

void RegisterVolumes(py::module_& m) {
  BindVolume(m);
  BindSequence(m);
}

}  // namespace echoservo::python
