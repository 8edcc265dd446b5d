#include "imaging/sim/scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace echoservo::imaging::sim {
namespace {

void Require(bool ok, const std::string& where, const std::string& field, const std::string& what) {
  if (!ok) throw std::invalid_argument(where + ": " + field + " " + what);
}

void RequireSceneRange(double v, double lo, double hi, const std::string& where,
                       const std::string& field) {
  if (!(std::isfinite(v) && v >= lo && v <= hi)) {
    std::ostringstream os;
    os << where << ": " << field << " must be in [" << lo << ", " << hi << "], got " << v;
    throw std::invalid_argument(os.str());
  }
}

void RequirePositive(double v, const std::string& where, const std::string& field) {
  if (!(std::isfinite(v) && v > 0.0)) {
    std::ostringstream os;
    os << where << ": " << field << " must be finite and > 0, got " << v;
    throw std::invalid_argument(os.str());
  }
}

}  // namespace

void AcousticProperties::Validate(const std::string& where) const {
  RequireSceneRange(specular, 0, 10, where, "specular");
  RequireSceneRange(specularity, 0, 1000, where, "specularity");
  RequireSceneRange(diffuse, 0, 10, where, "diffuse");
  RequireSceneRange(transmission, 0, 1, where, "transmission");
  RequireSceneRange(scatter, 0, 10, where, "scatter");
  RequireSceneRange(reverb_count, 0, 16, where, "reverb_count");
  Require(std::isfinite(reverb_decay) && reverb_decay >= 0 && reverb_decay < 1, where,
          "reverb_decay", "must be in [0, 1)");
}

AcousticProperties AcousticProperties::Sheath() {
  AcousticProperties p;
  p.specular = 0.6;
  p.specularity = 3.0;
  p.diffuse = 0.08;
  p.transmission = 0.35;
  p.scatter = 0.0;
  return p;
}
AcousticProperties AcousticProperties::Guidewire() {
  AcousticProperties p;
  p.specular = 1.0;
  p.specularity = 2.0;
  p.diffuse = 0.15;
  p.transmission = 0.5;
  p.is_metal = true;
  p.reverb_count = 8;
  p.reverb_decay = 0.6;
  return p;
}
AcousticProperties AcousticProperties::Tissue() {
  AcousticProperties p;
  p.specular = 0.15;
  p.specularity = 6.0;
  p.diffuse = 0.04;
  p.transmission = 0.9;
  p.scatter = 0.06;
  return p;
}
AcousticProperties AcousticProperties::TankWall() {
  AcousticProperties p;
  p.specular = 0.4;
  p.specularity = 8.0;
  p.diffuse = 0.05;
  p.transmission = 0.0;
  return p;
}

TriangleMesh MakeCylinder(double radius_mm, double length_mm, int segments) {
  const std::string where = "MakeCylinder";
  RequirePositive(radius_mm, where, "radius_mm");
  RequirePositive(length_mm, where, "length_mm");
  RequireSceneRange(segments, 3, 4096, where, "segments");
  TriangleMesh m;
  const int n = segments;
  for (int ring = 0; ring < 2; ++ring) {
    const double z = ring == 0 ? 0.0 : length_mm;
    for (int i = 0; i < n; ++i) {
      const double a = 2.0 * std::numbers::pi * i / n;
      m.vertices.emplace_back(static_cast<float>(radius_mm * std::cos(a)),
                              static_cast<float>(radius_mm * std::sin(a)), static_cast<float>(z));
    }
  }
  m.vertices.emplace_back(0.f, 0.f, 0.f);
  m.vertices.emplace_back(0.f, 0.f, static_cast<float>(length_mm));
  const int c0 = 2 * n, c1 = 2 * n + 1;
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.triangles.emplace_back(i, j, n + j);
    m.triangles.emplace_back(i, n + j, n + i);
    m.triangles.emplace_back(c0, j, i);
    m.triangles.emplace_back(c1, n + i, n + j);
  }
  return m;
}

TriangleMesh MakeBox(const Eigen::Vector3d& min_mm, const Eigen::Vector3d& max_mm) {
  const std::string where = "MakeBox";
  Require(min_mm.allFinite() && max_mm.allFinite(), where, "min_mm/max_mm", "must be finite");
  Require((max_mm - min_mm).minCoeff() > 0, where, "max_mm", "must exceed min_mm on every axis");
  TriangleMesh m;
  for (int k = 0; k < 8; ++k) {
    m.vertices.emplace_back(static_cast<float>((k & 1) ? max_mm.x() : min_mm.x()),
                            static_cast<float>((k & 2) ? max_mm.y() : min_mm.y()),
                            static_cast<float>((k & 4) ? max_mm.z() : min_mm.z()));
  }
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.emplace_back(q[0], q[1], q[2]);
    m.triangles.emplace_back(q[0], q[2], q[3]);
  }
  return m;
}

double SaddleHeightMm(double diameter_mm, double saddle_mm, double x_mm, double y_mm) {
  const double r = 0.5 * diameter_mm;
  const double rho2 = (x_mm * x_mm + y_mm * y_mm) / (r * r);
  const double phi = std::atan2(y_mm, x_mm);
  return saddle_mm * rho2 * std::cos(2.0 * phi);
}

TriangleMesh MakeSaddleDisc(double diameter_mm, double thickness_mm, double saddle_mm, int rings,
                            int segments) {
  const std::string where = "MakeSaddleDisc";
  RequirePositive(diameter_mm, where, "diameter_mm");
  RequirePositive(thickness_mm, where, "thickness_mm");
  RequireSceneRange(saddle_mm, -diameter_mm, diameter_mm, where, "saddle_mm");
  RequireSceneRange(rings, 1, 1024, where, "rings");
  RequireSceneRange(segments, 3, 4096, where, "segments");
  TriangleMesh m;
  const double r = 0.5 * diameter_mm;
  // Vertex (side s ∈ {0 bottom, 1 top}, ring k ∈ [1, rings], segment i); centres first.
  auto vid = [&](int side, int k, int i) {
    return 2 + side * rings * segments + (k - 1) * segments + i;
  };
  for (int side = 0; side < 2; ++side) {
    const double dz = (side == 0 ? -0.5 : 0.5) * thickness_mm;
    m.vertices.emplace_back(0.f, 0.f, static_cast<float>(dz));
  }
  for (int side = 0; side < 2; ++side) {
    const double dz = (side == 0 ? -0.5 : 0.5) * thickness_mm;
    for (int k = 1; k <= rings; ++k) {
      const double rho = r * k / rings;
      for (int i = 0; i < segments; ++i) {
        const double a = 2.0 * std::numbers::pi * i / segments;
        const double x = rho * std::cos(a), y = rho * std::sin(a);
        m.vertices.emplace_back(
            static_cast<float>(x), static_cast<float>(y),
            static_cast<float>(SaddleHeightMm(diameter_mm, saddle_mm, x, y) + dz));
      }
    }
  }
  for (int side = 0; side < 2; ++side) {
    const bool top = side == 1;
    for (int i = 0; i < segments; ++i) {
      const int j = (i + 1) % segments;
      if (top)
        m.triangles.emplace_back(1, vid(1, 1, i), vid(1, 1, j));
      else
        m.triangles.emplace_back(0, vid(0, 1, j), vid(0, 1, i));
      for (int k = 1; k < rings; ++k) {
        const int a = vid(side, k, i), b = vid(side, k, j), c = vid(side, k + 1, j),
                  d = vid(side, k + 1, i);
        if (top) {
          m.triangles.emplace_back(a, d, c);
          m.triangles.emplace_back(a, c, b);
        } else {
          m.triangles.emplace_back(a, b, c);
          m.triangles.emplace_back(a, c, d);
        }
      }
    }
  }
  for (int i = 0; i < segments; ++i) {  // rim
    const int j = (i + 1) % segments;
    const int b0 = vid(0, rings, i), b1 = vid(0, rings, j), t0 = vid(1, rings, i),
              t1 = vid(1, rings, j);
    m.triangles.emplace_back(b0, b1, t1);
    m.triangles.emplace_back(b0, t1, t0);
  }
  return m;
}

namespace {

TriangleMesh LoadObj(const std::string& path) {
  std::ifstream in(path);
  Require(static_cast<bool>(in), "LoadMeshFile", "path", "'" + path + "' cannot be opened");
  TriangleMesh m;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") {
      float x, y, z;
      Require(static_cast<bool>(ls >> x >> y >> z), "LoadMeshFile", "path",
              "'" + path + "': bad vertex line");
      m.vertices.emplace_back(x, y, z);
    } else if (tag == "f") {
      std::vector<int> idx;
      std::string tok;
      while (ls >> tok) {
        int v = std::stoi(tok.substr(0, tok.find('/')));
        v = v < 0 ? static_cast<int>(m.vertices.size()) + v : v - 1;
        idx.push_back(v);
      }
      for (std::size_t k = 2; k < idx.size(); ++k)
        m.triangles.emplace_back(idx[0], idx[k - 1], idx[k]);
    }
  }
  return m;
}

TriangleMesh LoadStl(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  Require(static_cast<bool>(in), "LoadMeshFile", "path", "'" + path + "' cannot be opened");
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  TriangleMesh m;
  auto add = [&](const float* v) {
    const int base = static_cast<int>(m.vertices.size());
    for (int k = 0; k < 3; ++k) m.vertices.emplace_back(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
    m.triangles.emplace_back(base, base + 1, base + 2);
  };
  if (data.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, data.data() + 80, 4);
    if (data.size() == 84 + 50ull * n) {
      for (std::uint32_t t = 0; t < n; ++t) {
        float v[9];
        std::memcpy(v, data.data() + 84 + 50ull * t + 12, sizeof v);
        add(v);
      }
      return m;
    }
  }
  std::istringstream ss(data);
  std::string tok;
  std::vector<float> v;
  while (ss >> tok) {
    if (tok == "vertex") {
      float x, y, z;
      ss >> x >> y >> z;
      v.insert(v.end(), {x, y, z});
      if (v.size() == 9) {
        add(v.data());
        v.clear();
      }
    }
  }
  return m;
}

}  // namespace

TriangleMesh LoadMeshFile(const std::string& path) {
  std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  TriangleMesh m;
  if (ext == ".obj")
    m = LoadObj(path);
  else if (ext == ".stl")
    m = LoadStl(path);
  else
    throw std::invalid_argument("LoadMeshFile: path '" + path + "' must end in .obj or .stl");
  Require(!m.triangles.empty(), "LoadMeshFile", "path", "'" + path + "' holds no triangles");
  return m;
}

struct Scene::Impl {
  struct Entry {
    TriangleMesh mesh;
    AcousticProperties props;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    RTCGeometry geom = nullptr;
    unsigned geom_id = 0;
    bool enabled = true;
  };
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Entry> entries;
  std::vector<int> geom_to_mesh;

  void WriteVertices(Entry& e) {
    auto* v = static_cast<float*>(rtcGetGeometryBufferData(e.geom, RTC_BUFFER_TYPE_VERTEX, 0));
    const Eigen::Matrix3f r = e.pose.linear().cast<float>();
    const Eigen::Vector3f t = e.pose.translation().cast<float>();
    for (std::size_t i = 0; i < e.mesh.vertices.size(); ++i) {
      const Eigen::Vector3f w = r * e.mesh.vertices[i] + t;
      v[3 * i] = w.x();
      v[3 * i + 1] = w.y();
      v[3 * i + 2] = w.z();
    }
    rtcUpdateGeometryBuffer(e.geom, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(e.geom);
  }
};

Scene::Scene() : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (!impl_->device) throw std::runtime_error("Scene: rtcNewDevice failed");
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneFlags(
      impl_->scene,
      static_cast<RTCSceneFlags>(RTC_SCENE_FLAG_DYNAMIC |
                                 RTC_SCENE_FLAG_ROBUST));  // robust: rays through shared vertices
                                                           // (the truth ray hits the disc centre)
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_LOW);
}

Scene::~Scene() {
  for (auto& e : impl_->entries) rtcReleaseGeometry(e.geom);
  rtcReleaseScene(impl_->scene);
  rtcReleaseDevice(impl_->device);
}

int Scene::AddMesh(TriangleMesh mesh, const AcousticProperties& properties,
                   const Eigen::Isometry3d& mesh_to_world) {
  const std::string where = "Scene::AddMesh";
  properties.Validate(where + " properties");
  Require(!mesh.triangles.empty() && !mesh.vertices.empty(), where, "mesh", "is empty");
  const int nv = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles)
    Require(t.minCoeff() >= 0 && t.maxCoeff() < nv, where, "mesh.triangles", "index out of range");
  for (const auto& v : mesh.vertices)
    Require(v.allFinite(), where, "mesh.vertices", "must be finite");
  Require(mesh_to_world.matrix().allFinite(), where, "mesh_to_world", "must be finite");
  Impl::Entry e;
  e.mesh = std::move(mesh);
  e.props = properties;
  e.pose = mesh_to_world;
  e.geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetNewGeometryBuffer(e.geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                          e.mesh.vertices.size());
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(e.geom, RTC_BUFFER_TYPE_INDEX, 0,
                                                             RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                             e.mesh.triangles.size()));
  for (std::size_t i = 0; i < e.mesh.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) idx[3 * i + k] = static_cast<unsigned>(e.mesh.triangles[i][k]);
  impl_->WriteVertices(e);
  e.geom_id = rtcAttachGeometry(impl_->scene, e.geom);
  if (impl_->geom_to_mesh.size() <= e.geom_id) impl_->geom_to_mesh.resize(e.geom_id + 1, -1);
  impl_->geom_to_mesh[e.geom_id] = static_cast<int>(impl_->entries.size());
  impl_->entries.push_back(std::move(e));
  return static_cast<int>(impl_->entries.size()) - 1;
}

void Scene::SetPose(int id, const Eigen::Isometry3d& mesh_to_world) {
  Require(id >= 0 && id < mesh_count(), "Scene::SetPose", "id", "out of range");
  Require(mesh_to_world.matrix().allFinite(), "Scene::SetPose", "mesh_to_world", "must be finite");
  auto& e = impl_->entries[static_cast<std::size_t>(id)];
  e.pose = mesh_to_world;
  impl_->WriteVertices(e);
}

void Scene::SetEnabled(int id, bool enabled) {
  Require(id >= 0 && id < mesh_count(), "Scene::SetEnabled", "id", "out of range");
  auto& e = impl_->entries[static_cast<std::size_t>(id)];
  if (e.enabled == enabled) return;
  e.enabled = enabled;
  if (enabled)
    rtcEnableGeometry(e.geom);
  else
    rtcDisableGeometry(e.geom);
  rtcCommitGeometry(e.geom);
}

void Scene::Commit() { rtcCommitScene(impl_->scene); }

int Scene::mesh_count() const { return static_cast<int>(impl_->entries.size()); }
const AcousticProperties& Scene::properties(int id) const {
  return impl_->entries.at(static_cast<std::size_t>(id)).props;
}
const Eigen::Isometry3d& Scene::pose(int id) const {
  return impl_->entries.at(static_cast<std::size_t>(id)).pose;
}

int Scene::TraceAll(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                    RayHit* hits, int max_hits) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  float t_near = 0.0f;
  int n = 0;
  std::uint32_t parity[64] = {};  // crossing parity of meshes 0..2047, one bit each
  while (n < max_hits) {
    RTCRayHit rh;
    rh.ray.org_x = origin.x();
    rh.ray.org_y = origin.y();
    rh.ray.org_z = origin.z();
    rh.ray.dir_x = direction.x();
    rh.ray.dir_y = direction.y();
    rh.ray.dir_z = direction.z();
    rh.ray.tnear = t_near;
    rh.ray.tfar = t_max;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
    const int mesh = impl_->geom_to_mesh[rh.hit.geomID];
    const float ng = std::sqrt(rh.hit.Ng_x * rh.hit.Ng_x + rh.hit.Ng_y * rh.hit.Ng_y +
                               rh.hit.Ng_z * rh.hit.Ng_z);
    const float d =
        rh.hit.Ng_x * direction.x() + rh.hit.Ng_y * direction.y() + rh.hit.Ng_z * direction.z();
    RayHit& h = hits[n++];
    h.t_mm = rh.ray.tfar;
    h.cos_incidence = ng > 0 ? std::min(1.0f, std::abs(d) / ng) : 0.0f;
    h.mesh = mesh;
    bool entering = true;
    if (mesh < 64 * 32) {
      std::uint32_t& word = parity[mesh / 32];
      const std::uint32_t bit = 1u << (mesh % 32);
      entering = (word & bit) == 0;
      word ^= bit;
    }
    h.entering = entering;
    t_near = rh.ray.tfar + 1e-3f;
  }
  return n;
}

bool Scene::FirstHitOn(int id, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                       double t_max, RayHit* hit) const {
  RayHit hits[32];
  const int n = TraceAll(origin.cast<float>(), direction.normalized().cast<float>(),
                         static_cast<float>(t_max), hits, 32);
  for (int i = 0; i < n; ++i) {
    if (hits[i].mesh == id) {
      *hit = hits[i];
      return true;
    }
  }
  return false;
}

}  // namespace echoservo::imaging::sim
