// Freehand reconstruction (imaging/reconstruct/freehand_reconstruction.h) on synthetic
// sweeps generated here: a plane imaged at known poses through a phantom of known geometry
// (spheres, a uniform slab). The generator computes each pixel's position directly from the
// pose and calibration (no reconstruction code), so the phantom's reconstructed position is
// checked against the truth within half a voxel.
#include "imaging/reconstruct/freehand_reconstruction.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "imaging/io/volume_io.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::imaging {
namespace {

std::string Matrix16(const Eigen::Matrix4d& m) {
  std::ostringstream s;
  s.precision(17);
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) s << m(r, c) << ' ';
  }
  return s.str();
}

struct Sweep {
  int width = 60, height = 50;
  double mm_per_pixel = 0.2;
  Eigen::Matrix4d image_to_probe = Eigen::Matrix4d::Identity();
  std::vector<Eigen::Matrix4d> probe_to_tracker;
};

// Image → probe: x → probe x, y → probe y, at mm_per_pixel, shifted by (−3, 1) mm.
Eigen::Matrix4d Calibration(double mm_per_pixel) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = mm_per_pixel;
  m(1, 1) = mm_per_pixel;
  m(2, 2) = mm_per_pixel;
  m(0, 3) = -3.0;
  m(1, 3) = 1.0;
  return m;
}

// A sequence whose pixel (i, j) of frame f has the value `value(point in tracker frame)`.
template <typename Phantom>
PlusSequence MakeSequence(const Sweep& sweep, Phantom value, bool calibration_in_frames) {
  PlusSequence s;
  s.frame_dims = {sweep.width, sweep.height, 1};
  const std::size_t n = sweep.probe_to_tracker.size();
  s.pixels.resize(n * sweep.width * sweep.height);
  for (std::size_t f = 0; f < n; ++f) {
    SequenceFrame frame;
    frame.fields["ProbeToTrackerTransform"] = Matrix16(sweep.probe_to_tracker[f]);
    frame.fields["ProbeToTrackerTransformStatus"] = "OK";
    frame.fields["ImageStatus"] = "OK";
    if (calibration_in_frames) {
      frame.fields["ImageToProbeTransform"] = Matrix16(sweep.image_to_probe);
    }
    s.frames.push_back(frame);
    const Eigen::Matrix4d m = sweep.probe_to_tracker[f] * sweep.image_to_probe;
    for (int j = 0; j < sweep.height; ++j) {
      for (int i = 0; i < sweep.width; ++i) {
        const Eigen::Vector3d p = (m * Eigen::Vector4d(i, j, 0, 1)).head<3>();
        s.pixels[f * sweep.width * sweep.height + j * sweep.width + i] = value(p);
      }
    }
  }
  return s;
}

Eigen::Matrix4d Pose(double angle_x_deg, double angle_y_deg, const Eigen::Vector3d& t) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  const double kDeg = M_PI / 180.0;
  m.topLeftCorner<3, 3>() = (Eigen::AngleAxisd(angle_x_deg * kDeg, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(angle_y_deg * kDeg, Eigen::Vector3d::UnitY()))
                                .toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

// Intensity-weighted centroid (mm) of the voxels above `threshold` within `radius_mm` of
// `near`.
Eigen::Vector3d Centroid(const Volume& v, const Eigen::Vector3d& near, double radius_mm,
                         int threshold) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double w = 0.0;
  for (int k = 0; k < v.dims().z(); ++k) {
    for (int j = 0; j < v.dims().y(); ++j) {
      for (int i = 0; i < v.dims().x(); ++i) {
        const int value = v.at(i, j, k);
        if (value <= threshold) continue;
        const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(i, j, k));
        if ((p - near).norm() > radius_mm) continue;
        sum += (value - threshold) * p;
        w += value - threshold;
      }
    }
  }
  EXPECT_GT(w, 0.0) << "no bright voxel near " << near.transpose();
  return w > 0 ? Eigen::Vector3d(sum / w) : Eigen::Vector3d::Constant(NAN);
}

// A tilted sweep of 40 frames, 0.25 mm apart along the plane normal, with a slowly changing
// tilt, through two spheres of radius 1.2 mm.
Sweep TiltedSweep() {
  Sweep sweep;
  sweep.image_to_probe = Calibration(sweep.mm_per_pixel);
  for (int f = 0; f < 40; ++f) {
    const double tilt = 10.0 + 0.05 * f;
    Eigen::Matrix4d pose = Pose(tilt, -7.0, Eigen::Vector3d(20.0, -4.0, 7.0));
    pose.topRightCorner<3, 1>() += pose.block<3, 1>(0, 2) * (0.25 * f);
    sweep.probe_to_tracker.push_back(pose);
  }
  return sweep;
}

TEST(FreehandReconstruction, SyntheticSpheresLandWithinHalfAVoxel) {
  const Sweep sweep = TiltedSweep();
  // Sphere centres: in the middle of the sweep, in two places of the image.
  const Eigen::Matrix4d mid = sweep.probe_to_tracker[20] * sweep.image_to_probe;
  const Eigen::Vector3d a = (mid * Eigen::Vector4d(15, 20, 0, 1)).head<3>();
  const Eigen::Vector3d b = (mid * Eigen::Vector4d(42, 33, 0, 1)).head<3>() +
                            sweep.probe_to_tracker[20].block<3, 1>(0, 2) * 1.3;
  const double radius_mm = 1.2;
  const PlusSequence seq = MakeSequence(
      sweep,
      [&](const Eigen::Vector3d& p) {
        return static_cast<std::uint8_t>(
            ((p - a).norm() < radius_mm || (p - b).norm() < radius_mm) ? 220 : 20);
      },
      /*calibration_in_frames=*/true);
  for (const Compounding method :
       {Compounding::kWeighted, Compounding::kNearestLast, Compounding::kNearestMean}) {
    ReconstructionOptions o;
    o.spacing_mm = 0.5;
    o.compounding = method;
    const ReconstructionResult r = ReconstructFreehand(seq, o);
    EXPECT_EQ(r.frames_used, 40u);
    EXPECT_EQ(r.FramesSkipped(), 0u);
    EXPECT_EQ(r.calibration_source, "frame field ImageToProbeTransform");
    EXPECT_EQ(r.output_frame, "Tracker");
    // A compounded volume has no beam geometry: it claims no image-to-probe transform.
    EXPECT_FALSE(r.volume.has_image_to_probe());
    // Half a voxel: the spheres are sampled by frames 0.25 mm apart and voxels 0.5 mm apart.
    // "Last wins" keeps, in each voxel, the pixel of the last frame through it, which lies
    // systematically on one side of the voxel centre (up to spacing/2 along the sweep) and
    // up to half a pixel away in the plane: its bound is the hypotenuse of the two.
    const double tol = method == Compounding::kNearestLast
                           ? std::hypot(o.spacing_mm / 2, sweep.mm_per_pixel / 2)
                           : o.spacing_mm / 2;
    EXPECT_LT((Centroid(r.volume, a, 2.5, 120) - a).norm(), tol) << static_cast<int>(method);
    EXPECT_LT((Centroid(r.volume, b, 2.5, 120) - b).norm(), tol) << static_cast<int>(method);
    // The extent: every frame's corner pixel lies inside the volume's box (within rounding).
    Eigen::AlignedBox3d box = r.volume.BoundingBoxMm();
    box.extend(box.min() - Eigen::Vector3d::Constant(1e-6));
    box.extend(box.max() + Eigen::Vector3d::Constant(o.spacing_mm));
    for (const Eigen::Matrix4d& pose : sweep.probe_to_tracker) {
      const Eigen::Matrix4d m = pose * sweep.image_to_probe;
      EXPECT_TRUE(box.contains((m * Eigen::Vector4d(0, 0, 0, 1)).head<3>()));
      EXPECT_TRUE(box.contains((m * Eigen::Vector4d(59, 49, 0, 1)).head<3>()));
    }
  }
}

TEST(FreehandReconstruction, ReferenceFrameAndCalibrationSources) {
  Sweep sweep = TiltedSweep();
  sweep.probe_to_tracker.resize(10);
  const Eigen::Matrix4d mid = sweep.probe_to_tracker[5] * sweep.image_to_probe;
  const Eigen::Vector3d a = (mid * Eigen::Vector4d(30, 25, 0, 1)).head<3>();
  PlusSequence seq = MakeSequence(
      sweep, [&](const Eigen::Vector3d& p) { return std::uint8_t((p - a).norm() < 1.0 ? 200 : 0); },
      /*calibration_in_frames=*/false);
  // No calibration anywhere: a clear error.
  try {
    ReconstructFreehand(seq);
    FAIL() << "expected an error for the missing calibration";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("image-to-probe"), std::string::npos) << e.what();
  }
  // From the header.
  seq.header_fields.emplace_back("ImageToProbeTransform", Matrix16(sweep.image_to_probe));
  EXPECT_EQ(ReconstructFreehand(seq).calibration_source, "header field ImageToProbeTransform");
  // A reference tool: the output is in its frame, so the sphere moves by its inverse.
  const Eigen::Matrix4d ref_to_tracker = Pose(30.0, 5.0, Eigen::Vector3d(-50, 12, 100));
  for (SequenceFrame& f : seq.frames) {
    f.fields["ReferenceToTrackerTransform"] = Matrix16(ref_to_tracker);
  }
  ReconstructionOptions o;
  o.reference_tool = "Reference";
  const ReconstructionResult r = ReconstructFreehand(seq, o);
  EXPECT_EQ(r.output_frame, "Reference");
  const Eigen::Vector3d a_ref = (ref_to_tracker.inverse() * a.homogeneous()).head<3>();
  EXPECT_LT((Centroid(r.volume, a_ref, 2.0, 100) - a_ref).norm(), o.spacing_mm / 2);
  // A bad calibration option: singular, non-finite.
  o.image_to_probe = Eigen::Matrix4d::Identity();
  (*o.image_to_probe)(2, 2) = 0.0;
  (*o.image_to_probe)(1, 1) = 0.0;
  EXPECT_THROW(ReconstructFreehand(seq, o), std::invalid_argument);
  (*o.image_to_probe) = Eigen::Matrix4d::Identity();
  (*o.image_to_probe)(0, 3) = NAN;
  EXPECT_THROW(ReconstructFreehand(seq, o), std::invalid_argument);
}

// Frames with missing, INVALID, non-finite or non-rigid transforms, or INVALID images, are
// skipped and counted; the rest still reconstruct.
TEST(FreehandReconstruction, InvalidFramesSkippedAndCounted) {
  Sweep sweep = TiltedSweep();
  sweep.probe_to_tracker.resize(12);
  PlusSequence seq = MakeSequence(
      sweep, [](const Eigen::Vector3d&) { return std::uint8_t(90); }, true);
  seq.frames[1].fields["ProbeToTrackerTransformStatus"] = "INVALID";
  seq.frames[2].fields["ProbeToTrackerTransformStatus"] = "INVALID";
  seq.frames[3].fields.erase("ProbeToTrackerTransform");
  seq.frames[3].fields.erase("ProbeToTrackerTransformStatus");
  seq.frames[4].fields["ProbeToTrackerTransform"] = "1 0 0 nan 0 1 0 0 0 0 1 0 0 0 0 1";
  seq.frames[5].fields["ProbeToTrackerTransform"] = "2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";  // scaled
  seq.frames[6].fields["ImageStatus"] = "INVALID";
  seq.frames[7].fields["ImageToProbeTransformStatus"] = "INVALID";
  const ReconstructionResult r = ReconstructFreehand(seq);
  EXPECT_EQ(r.frames_total, 12u);
  EXPECT_EQ(r.frames_used, 5u);
  EXPECT_EQ(r.skipped_invalid_status, 3u);
  EXPECT_EQ(r.skipped_missing_transform, 1u);
  EXPECT_EQ(r.skipped_bad_transform, 2u);
  EXPECT_EQ(r.skipped_image_status, 1u);
  EXPECT_EQ(r.FramesSkipped(), 7u);
  // Every frame invalid: an error listing the reasons, not an empty volume.
  for (SequenceFrame& f : seq.frames) f.fields["ProbeToTrackerTransformStatus"] = "INVALID";
  try {
    ReconstructFreehand(seq);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no usable frame"), std::string::npos) << e.what();
  }
}

// Frames exactly on voxel planes 0.5 mm apart (nearest compounding): one missing frame
// leaves a one-voxel gap, filled by the 3×3×3 kernel with the neighbours' value; three
// missing frames leave a gap wider than the kernel whose middle plane stays empty.
TEST(FreehandReconstruction, HoleFillingFillsGapNarrowerThanKernel) {
  Sweep sweep;
  sweep.width = 20;
  sweep.height = 16;
  sweep.mm_per_pixel = 0.5;
  sweep.image_to_probe = Eigen::Matrix4d::Identity();
  sweep.image_to_probe.topLeftCorner<3, 3>() *= 0.5;
  for (int f = 0; f < 16; ++f) sweep.probe_to_tracker.push_back(Pose(0, 0, {1, 2, 0.5 * f}));
  PlusSequence seq = MakeSequence(
      sweep, [](const Eigen::Vector3d&) { return std::uint8_t(77); }, true);
  seq.frames[4].fields["ProbeToTrackerTransformStatus"] = "INVALID";  // gap at plane 4
  for (int f : {9, 10, 11}) seq.frames[f].fields["ProbeToTrackerTransformStatus"] = "INVALID";
  ReconstructionOptions o;
  o.compounding = Compounding::kNearestLast;
  o.fill_holes = false;
  const ReconstructionResult raw = ReconstructFreehand(seq, o);
  ASSERT_EQ(raw.volume.dims(), Eigen::Vector3i(20, 16, 16));
  EXPECT_EQ(raw.volume.at(10, 8, 4), 0);
  EXPECT_EQ(raw.volume.at(10, 8, 3), 77);
  EXPECT_EQ(raw.voxels_filled_holes, 0);
  o.fill_holes = true;
  const ReconstructionResult filled = ReconstructFreehand(seq, o);
  for (int j = 1; j < 15; ++j) {
    for (int i = 1; i < 19; ++i) {
      ASSERT_EQ(filled.volume.at(i, j, 4), 77) << i << "," << j;
      ASSERT_EQ(filled.volume.at(i, j, 10), 0) << i << "," << j;  // middle of the wide gap
    }
  }
  EXPECT_GE(filled.voxels_filled_holes, 18 * 14);  // plane 4's interior at least
}

TEST(FreehandReconstruction, SizeLimitRefusedWithTheNumbers) {
  const Sweep sweep = TiltedSweep();
  const PlusSequence seq = MakeSequence(
      sweep, [](const Eigen::Vector3d&) { return std::uint8_t(1); }, true);
  ReconstructionOptions o;
  o.max_voxels = 1000;
  try {
    ReconstructFreehand(seq, o);
    FAIL() << "expected the size limit";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("limit of 1000"), std::string::npos) << what;
    EXPECT_NE(what.find(" voxels"), std::string::npos) << what;
  }
  // A huge region at a fine spacing is refused before allocating anything.
  o.max_voxels = 512LL * 512 * 512;
  o.roi_mm = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1e6), Eigen::Vector3d::Constant(1e6));
  o.spacing_mm = 0.01;
  EXPECT_THROW(ReconstructFreehand(seq, o), std::invalid_argument);
  // Bad options.
  ReconstructionOptions bad;
  bad.spacing_mm = 0.0;
  EXPECT_THROW(ReconstructFreehand(seq, bad), std::invalid_argument);
  bad.spacing_mm = NAN;
  EXPECT_THROW(ReconstructFreehand(seq, bad), std::invalid_argument);
  bad = {};
  bad.roi_mm = Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, -1, 1));
  EXPECT_THROW(ReconstructFreehand(seq, bad), std::invalid_argument);
}

TEST(FreehandReconstruction, UnsupportedSequencesRejected) {
  PlusSequence tracker_only;
  tracker_only.frame_dims = {0, 0, 1};
  tracker_only.element_type = "MET_OTHER";
  tracker_only.frames.resize(3);
  EXPECT_THROW(ReconstructFreehand(tracker_only), std::invalid_argument);
  PlusSequence volumes;
  volumes.frame_dims = {4, 4, 4};
  volumes.volume_frames = true;
  volumes.frames.resize(1);
  volumes.pixels.resize(64);
  EXPECT_THROW(ReconstructFreehand(volumes), std::invalid_argument);
}

// Against an independent implementation: PLUS's own reconstruction of its spine phantom
// sweep (data/plus/SpinePhantomFreehandReconstructed.mha, 0.5 mm, Reference frame), with
// the calibration of PLUS's spine-phantom reconstruction configs
// (PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_*.xml, docs/reconstruction.md).
TEST(FreehandReconstruction, SpineSweepMatchesPlusReconstruction) {
  ECHOSERVO_RELEASE_SUITE_ONLY("real 21-frame sweep and a 1.6 M-voxel comparison");
  const std::string dir = std::string(ECHOSERVO_DATA_DIR) + "/plus/";
  const PlusSequence seq = ReadPlusSequence(dir + "SpinePhantomFreehand.igs.mha");
  ReconstructionOptions o;
  o.reference_tool = "Reference";
  o.image_to_probe = Eigen::Matrix4d();
  *o.image_to_probe << -0.00157821, 0.0785919, -0.00803285, 15.3978,  //
      -0.0839128, 0.00372697, 0.0153803, 49.5705,                     //
      0.0159024, 0.00714276, 0.0803604, -8.63446,                     //
      0, 0, 0, 1;
  const ReconstructionResult r = ReconstructFreehand(seq, o);
  const Volume plus = ReadVolume(dir + "SpinePhantomFreehandReconstructed.mha");
  // Same extent: the bounding box of the frames' corners, as PLUS computes it (PLUS writes
  // 6 significant digits).
  EXPECT_EQ(r.volume.dims(), plus.dims());
  EXPECT_LT((r.volume.origin_mm() - plus.origin_mm()).norm(), 1e-3);
  // Same content: the best integer-voxel alignment is no shift, and the intensities agree
  // (two resamplings of the same pixels differ only in interpolation details).
  const VolumeAgreement a = CompareVolumes(r.volume, plus, 2);
  EXPECT_EQ(a.best_shift_mm, Eigen::Vector3d::Zero());
  EXPECT_GT(a.correlation, 0.95);
  EXPECT_GT(a.overlap_voxels, plus.voxel_count() / 10);
}

}  // namespace
}  // namespace echoservo::imaging
