// A test backend for the node's plumbing tests (rostests): it segments the cloud into connected
// components on a 10 cm grid and returns each component of >= 30 points as an instance with its
// axis-aligned box, the box mesh, a class read from the points' colour (red channel * 8) and
// the component's points as support. Deterministic and computed from the input, so the tests
// can assert positions, ids, sources and support points. It optionally sleeps (to measure
// responsiveness while "inference" runs) or throws (a pipeline error). Not a reconstructor.
#pragma once

#include <atomic>
#include <chrono>
#include <thread>
#include <unordered_map>

#include "dimr/geometry/error.h"
#include "dimr/ros/scene_backend.h"

namespace dimr::ros1::testing {

struct BoxBackendControl {
  std::atomic<int> delay_ms{0};
  std::atomic<bool> fail_next{false};
  std::atomic<int> calls{0};
  std::atomic<int> last_points{0};
};

class BoxBackend : public SceneBackend {
 public:
  BoxBackend(bool with_pool, BoxBackendControl* control) : pool_(with_pool), ctl_(control) {}

  BackendResult Reconstruct(const BackendCloud& cloud) override {
    ++ctl_->calls;
    ctl_->last_points = static_cast<int>(cloud.points.size());
    if (ctl_->delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(ctl_->delay_ms));
    if (ctl_->fail_next.exchange(false)) throw Error("box backend: requested failure");
    const double cell = 0.10;
    auto key = [&](const Eigen::Vector3f& p, int dx, int dy, int dz) {
      const long long x = static_cast<long long>(std::floor(p.x() / cell)) + dx;
      const long long y = static_cast<long long>(std::floor(p.y() / cell)) + dy;
      const long long z = static_cast<long long>(std::floor(p.z() / cell)) + dz;
      return (x & 0x1fffff) | ((y & 0x1fffff) << 21) | ((z & 0x1fffff) << 42);
    };
    std::unordered_map<long long, std::vector<int>> cells;
    for (std::size_t i = 0; i < cloud.points.size(); ++i)
      cells[key(cloud.points[i], 0, 0, 0)].push_back(static_cast<int>(i));
    std::unordered_map<long long, int> comp;
    BackendResult r;
    int next = 0;
    std::vector<std::vector<int>> members;
    for (std::size_t i = 0; i < cloud.points.size(); ++i) {
      const long long k0 = key(cloud.points[i], 0, 0, 0);
      if (comp.count(k0)) continue;
      // Flood fill over 26-neighbour cells.
      std::vector<long long> stack = {k0};
      comp[k0] = next;
      members.emplace_back();
      while (!stack.empty()) {
        const long long k = stack.back();
        stack.pop_back();
        const std::vector<int>& pts = cells[k];
        members[next].insert(members[next].end(), pts.begin(), pts.end());
        const Eigen::Vector3f& p = cloud.points[pts[0]];
        for (int dx = -1; dx <= 1; ++dx)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dz = -1; dz <= 1; ++dz) {
              const long long n = key(p, dx, dy, dz);
              if (cells.count(n) && !comp.count(n)) {
                comp[n] = next;
                stack.push_back(n);
              }
            }
      }
      ++next;
    }
    for (std::vector<int>& m : members) {
      if (m.size() < 30) continue;
      std::sort(m.begin(), m.end());
      BackendInstance inst;
      geometry::AABB bb;
      float red = 0;
      for (int i : m) {
        bb.Extend(cloud.points[i].cast<double>());
        if (!cloud.colors.empty()) red += cloud.colors[i].x();
      }
      inst.cad_class =
          cloud.colors.empty() ? 0 : std::min(7, static_cast<int>(red / m.size() * 8.0f + 0.5f));
      inst.class_name = "class" + std::to_string(inst.cad_class);
      inst.score = 0.9f;
      inst.box.center = bb.Center();
      inst.box.size = bb.Extent().cwiseMax(geometry::Vec3::Constant(0.01));
      inst.mesh = inst.box.ToMesh();
      inst.source = mode_;
      if (mode_ != ShapeMode::kGeneration)
        inst.pool_model_id = "pool_" + std::to_string(inst.cad_class);
      inst.support = m;
      r.instances.push_back(std::move(inst));
    }
    r.timings_ms["total"] = 1.0;
    return r;
  }
  void SetMode(ShapeMode mode, int k) override {
    if (mode != ShapeMode::kGeneration && !pool_)
      throw InvalidArgument("box backend: no pool for " + std::string(ShapeModeName(mode)));
    mode_ = mode;
    k_ = k;
  }
  bool has_pool() const override { return pool_; }
  bool SupportsMode(ShapeMode mode, std::string* why) const override {
    if (mode == ShapeMode::kGeneration || pool_) return true;
    *why = "no CAD pool is loaded (parameter pipeline/pool)";
    return false;
  }
  std::string model_version() const override { return "box-test"; }
  std::string pool_id() const override { return pool_ ? "box-pool" : ""; }
  bool PoolModel(const std::string& id, geometry::TriangleMesh* mesh,
                 std::string* resource) const override {
    if (!pool_ || id.rfind("pool_", 0) != 0) return false;
    geometry::OrientedBox b;
    b.size = geometry::Vec3(2, 2, 2);
    *mesh = b.ToMesh();
    *resource = "";
    return true;
  }

 private:
  bool pool_;
  BoxBackendControl* ctl_;
  ShapeMode mode_ = ShapeMode::kGeneration;
  int k_ = 1;
};

}  // namespace dimr::ros1::testing
