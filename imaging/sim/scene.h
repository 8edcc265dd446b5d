// Acoustic scene of the simulated scanner: triangle meshes with acoustic properties,
// ray-traced with Embree 3.
//
// Units: mm, rad. Frames: every mesh is built in its own local frame (MeshToWorld places it
// in the world frame, the water tank's frame in which the probe and the catheter are posed).
// The Embree scene is built once; SetPose() rewrites one mesh's world-frame vertices and
// Commit() refits the BVH (meshes here have a few thousand triangles: < 0.1 ms per frame).
// Embree stays inside scene.cc; this header exposes only Eigen types.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace echoservo::imaging::sim {

// A triangle mesh in its local frame (mm).
struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Eigen::Vector3i> triangles;  // vertex indices, any winding
};

// How a surface returns and passes sound. Amplitudes are linear (1 = the strongest echo,
// shown at 0 dB). At a hit with incidence angle θ (between beam and surface normal) the
// echo amplitude is T · (specular · |cos θ|^specularity + diffuse), where T is the product
// of the `transmission` of all surfaces crossed before (shadowing). Inside a closed mesh
// with `scatter` > 0 (tissue), speckle of mean amplitude T · scatter fills the path.
// A metal mesh (`is_metal`) adds a comet tail: `reverb_count` echoes behind it, spaced by
// the path length through the mesh (its diameter along the beam), each `reverb_decay`
// times the previous one.
struct AcousticProperties {
  double specular = 0.5;      // [0, 10]
  double specularity = 4.0;   // exponent p of |cos θ|^p, [0, 1000]
  double diffuse = 0.02;      // [0, 10]
  double transmission = 0.8;  // per surface crossing, [0, 1]
  double scatter = 0.0;       // speckle amplitude inside the closed mesh, [0, 10]
  bool is_metal = false;
  int reverb_count = 6;       // [0, 16]
  double reverb_decay = 0.6;  // [0, 1)
  // Throws std::invalid_argument naming the field (prefixed by `where`).
  void Validate(const std::string& where = "acoustic properties") const;

  static AcousticProperties Sheath();     // polymer catheter sheath: bright, shadows
  static AcousticProperties Guidewire();  // nitinol/steel wire: very bright, comet tail
  static AcousticProperties Tissue();     // valve annulus: speckle, weak specular
  static AcousticProperties TankWall();   // acrylic tank wall: bright, opaque
};

// Builders (local frames; all throw std::invalid_argument naming the bad field).
// Closed cylinder of `radius_mm` between z = 0 and z = length_mm, axis +z.
TriangleMesh MakeCylinder(double radius_mm, double length_mm, int segments = 24);
// Closed axis-aligned box between `min_mm` and `max_mm`.
TriangleMesh MakeBox(const Eigen::Vector3d& min_mm, const Eigen::Vector3d& max_mm);
// Closed saddle-shaped disc (a closed mitral valve with its annulus): mid-surface
// z = saddle_mm · (ρ/R)² · cos 2φ for ρ ≤ R = diameter/2, `thickness_mm` thick (±t/2
// along z), normal +z.
TriangleMesh MakeSaddleDisc(double diameter_mm, double thickness_mm, double saddle_mm,
                            int rings = 12, int segments = 48);
// Mid-surface height of MakeSaddleDisc at local (x, y) (for truth computations).
double SaddleHeightMm(double diameter_mm, double saddle_mm, double x_mm, double y_mm);
// Wavefront OBJ (v / f lines; polygons fan-triangulated; "f a/b/c" forms accepted) or
// binary/ASCII STL, chosen by extension (.obj / .stl). Throws std::invalid_argument naming the
// path.
TriangleMesh LoadMeshFile(const std::string& path);

// One surface along a ray.
struct RayHit {
  float t_mm = 0.0f;           // distance along the (unit) ray
  float cos_incidence = 0.0f;  // |cos θ|
  int mesh = -1;               // Scene mesh id
  bool entering = false;       // by parity: the 1st, 3rd, ... crossing of a closed mesh
                               // (rays are assumed to start outside every closed mesh
                               // except the tank)
};

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // Adds a mesh posed by `mesh_to_world`; returns its id (0, 1, ...). Throws for an empty
  // mesh, an out-of-range index or invalid properties.
  int AddMesh(TriangleMesh mesh, const AcousticProperties& properties,
              const Eigen::Isometry3d& mesh_to_world = Eigen::Isometry3d::Identity());
  // Moves mesh `id`; takes effect at the next Commit().
  void SetPose(int id, const Eigen::Isometry3d& mesh_to_world);
  // Enables/disables mesh `id` (a disabled mesh is invisible to rays).
  void SetEnabled(int id, bool enabled);
  void Commit();

  int mesh_count() const;
  const AcousticProperties& properties(int id) const;
  const Eigen::Isometry3d& pose(int id) const;

  // All surfaces along origin + t · direction (unit) for t in (0, t_max], nearest first, at
  // most `max_hits`. Thread-safe after Commit(). Returns the number written to `hits`.
  int TraceAll(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
               RayHit* hits, int max_hits) const;
  // Nearest hit on mesh `id` only (other meshes are passed through); false if none.
  bool FirstHitOn(int id, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                  double t_max, RayHit* hit) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace echoservo::imaging::sim
