// Room composer: shapes, object counts, placement rules, no interpenetration, determinism.
#include "dimr/data/room.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/oriented_box.h"

namespace dimr::data {
namespace {

using geometry::Vec3;

bool Movable(const PlacedObject& o) {
  return o.role == ObjectRole::kFurniture || o.role == ObjectRole::kClutter;
}

// Distance from a 2-D point to the nearest outline edge.
double DistanceToOutline(const Room& room, const Eigen::Vector2d& p) {
  double best = 1e9;
  for (std::size_t i = 0; i < room.outline.size(); ++i) {
    const Eigen::Vector2d a = room.outline[i], b = room.outline[(i + 1) % room.outline.size()];
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (a + t * (b - a) - p).norm());
  }
  return best;
}

class RoomTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    RoomConfig cfg;
    for (std::uint64_t seed = 0; seed < 24; ++seed) rooms_.push_back(ComposeRoom(cfg, seed));
  }
  static std::vector<Room> rooms_;
};
std::vector<Room> RoomTest::rooms_;

TEST_F(RoomTest, ShapesCountsAndShell) {
  int l_rooms = 0, rect_rooms = 0;
  for (const Room& room : rooms_) {
    int movable = 0, walls = 0, floors = 0, doors = 0, ceilings = 0;
    for (const auto& o : room.objects) {
      movable += Movable(o);
      walls += o.role == ObjectRole::kWall;
      floors += o.role == ObjectRole::kFloor;
      doors += o.role == ObjectRole::kDoor;
      ceilings += o.role == ObjectRole::kCeiling;
    }
    EXPECT_GE(movable, 5);
    EXPECT_LE(movable, 25);
    EXPECT_EQ(walls, static_cast<int>(room.outline.size()));
    EXPECT_EQ(floors, 1);
    EXPECT_EQ(ceilings, 1);
    EXPECT_GE(doors, 1);
    if (room.shape == "L") {
      ++l_rooms;
      EXPECT_EQ(room.outline.size(), 6u);
    } else {
      ++rect_rooms;
      EXPECT_EQ(room.outline.size(), 4u);
    }
    EXPECT_GT(room.FloorArea(), 9.0);
    // Doors sit in a wall and open into the room: nothing sticks out behind the wall.
    for (const auto& o : room.objects) {
      if (o.role != ObjectRole::kDoor) continue;
      const Vec3 back = o.translation - o.Rotation() * Vec3(o.scale.x() / 2, 0, 0);
      EXPECT_LE(DistanceToOutline(room, back.head<2>()), room.wall_thickness + 0.006);
      EXPECT_FALSE(room.Inside(back.head<2>()));
    }
    // Every wall's room-facing side (canonical +x face) lies on the outline.
    for (const auto& o : room.objects) {
      if (o.role != ObjectRole::kWall) continue;
      const Vec3 face = o.translation + o.Rotation() * Vec3(o.scale.x() / 2, 0, 0);
      EXPECT_LT(DistanceToOutline(room, face.head<2>()), 1e-9);
      const Vec3 inward = o.translation + o.Rotation() * Vec3(o.scale.x() / 2 + 0.05, 0, 0);
      EXPECT_TRUE(room.Inside(inward.head<2>()));
      EXPECT_NEAR(o.scale.x(), 0.12, 1e-9);
      EXPECT_NEAR(o.scale.z(), room.height, 1e-9);
    }
  }
  EXPECT_GT(l_rooms, 2);
  EXPECT_GT(rect_rooms, 2);
}

TEST_F(RoomTest, NoInterpenetrationAndInsideRoom) {
  int pairs = 0;
  for (const Room& room : rooms_) {
    for (std::size_t i = 0; i < room.objects.size(); ++i) {
      const auto& a = room.objects[i];
      if (!Movable(a)) continue;
      for (const auto& c : a.Box().Corners()) {
        EXPECT_TRUE(room.Inside(c.head<2>())) << a.category;
        EXPECT_GE(c.z(), -1e-6);
        EXPECT_LE(c.z(), room.height);
      }
      for (std::size_t j = i + 1; j < room.objects.size(); ++j) {
        const auto& b = room.objects[j];
        if (!Movable(b)) continue;
        ++pairs;
        // Independent exact check (geometry's oriented-box IoU) of the composer's SAT test.
        EXPECT_LT(geometry::BoxIoU(a.Box(), b.Box()), 1e-9) << a.category << " vs " << b.category;
        EXPECT_FALSE(BoxesOverlap(a.Box(), b.Box()));
      }
    }
  }
  EXPECT_GT(pairs, 500);
}

TEST_F(RoomTest, PlacementRules) {
  int backs = 0, on_top = 0, mounted = 0, chairs_facing = 0, chairs_near = 0;
  for (const Room& room : rooms_) {
    for (const auto& o : room.objects) {
      if (!Movable(o)) continue;
      if (o.cad_class >= 0) {
        Vec3 lo, hi;
        CadSizeRange(o.cad_class, &lo, &hi);
        EXPECT_TRUE((o.scale.array() >= lo.array() - 1e-9).all() &&
                    (o.scale.array() <= hi.array() + 1e-9).all())
            << o.family << " size " << o.scale.transpose();
      }
      // Bookshelves and sofas stand with their back (-x face) against a wall.
      if (o.cad_class == kCadBookshelf || o.cad_class == kCadSofa || o.cad_class == kCadBathtub) {
        const Vec3 back = o.translation - o.Rotation() * Vec3(o.scale.x() / 2, 0, 0);
        EXPECT_LT(DistanceToOutline(room, back.head<2>()), 0.05) << o.family;
        const Vec3 front = o.translation + o.Rotation() * Vec3(o.scale.x() / 2 + 0.1, 0, 0);
        EXPECT_TRUE(room.Inside(front.head<2>()));
        ++backs;
      }
      if (o.support >= 0) {  // on top of another object, footprint on its top
        const auto& s = room.objects[o.support];
        const double bottom = o.translation.z() - o.scale.z() / 2;
        EXPECT_NEAR(bottom, s.translation.z() + s.scale.z() / 2, 2e-3);
        for (const auto& c : o.Box().Corners()) {
          const Vec3 d = s.Rotation().transpose() * (c - s.translation);
          EXPECT_LE(std::abs(d.x()), s.scale.x() / 2 + 1e-6);
          EXPECT_LE(std::abs(d.y()), s.scale.y() / 2 + 1e-6);
        }
        ++on_top;
      } else if (o.wall_mounted) {
        const Vec3 back = o.translation - o.Rotation() * Vec3(o.scale.x() / 2, 0, 0);
        EXPECT_LT(DistanceToOutline(room, back.head<2>()), 0.05) << o.category;
        EXPECT_GT(o.translation.z() - o.scale.z() / 2, 0.0);
        ++mounted;
      } else {
        EXPECT_NEAR(o.translation.z() - o.scale.z() / 2, 0.0, 1e-9) << o.category;
      }
    }
    // Chairs next to a dining table face it.
    for (const auto& c : room.objects) {
      if (c.cad_class != kCadChair) continue;
      for (const auto& t : room.objects) {
        if (t.cad_class != kCadTable || t.support >= 0 || t.scale.z() < 0.6) continue;
        const Vec3 d = t.translation - c.translation;
        if (d.head<2>().norm() > 0.5 * t.scale.head<2>().norm() + 0.6) continue;
        ++chairs_near;
        const Vec3 fwd = c.Rotation().col(0);
        chairs_facing += fwd.head<2>().dot(d.head<2>().normalized()) > 0.7;
      }
    }
  }
  EXPECT_GT(backs, 10);
  EXPECT_GT(on_top, 10);
  EXPECT_GT(mounted, 5);
  EXPECT_GT(chairs_near, 10);
  EXPECT_GE(chairs_facing, 0.8 * chairs_near);
}

TEST_F(RoomTest, CanonicalMeshesAndDeterminism) {
  for (const auto& o : rooms_[0].objects) {
    const geometry::AABB b = o.mesh.Bounds();
    EXPECT_NEAR(b.min.minCoeff(), -0.5, 1e-9);
    EXPECT_NEAR(b.max.maxCoeff(), 0.5, 1e-9);
    const geometry::AABB w = o.WorldMesh().Bounds();
    EXPECT_NEAR(w.Extent().z(), o.scale.z(), 1e-9);
  }
  const Room again = ComposeRoom(RoomConfig(), 0);
  ASSERT_EQ(again.objects.size(), rooms_[0].objects.size());
  for (std::size_t i = 0; i < again.objects.size(); ++i) {
    EXPECT_EQ(again.objects[i].translation, rooms_[0].objects[i].translation);
    EXPECT_EQ(again.objects[i].model_id, rooms_[0].objects[i].model_id);
    EXPECT_EQ(again.objects[i].mesh.vertices, rooms_[0].objects[i].mesh.vertices);
  }
  const Room other = ComposeRoom(RoomConfig(), 1);
  EXPECT_NE(other.objects[0].scale, rooms_[0].objects[0].scale);
}

// RoomConfig::window_pane: every window of a room gets one pane when the probability is 1: a
// 1 cm slab labelled window, inside its frame's opening, parallel to its wall and set back 1-7 cm
// from the wall's inner face; glass and blinds both occur. With 0 nothing is added.
TEST(RoomWindowPaneTest, PanesSitInTheOpeningSetBackFromTheWallFace) {
  RoomConfig cfg;
  cfg.window_pane = 1.0;
  int frames = 0, glass = 0, blinds = 0;
  for (std::uint64_t seed = 0; seed < 16; ++seed) {
    const Room room = ComposeRoom(cfg, seed);
    std::vector<const PlacedObject*> walls, window_frames, panes;
    for (const auto& o : room.objects) {
      if (o.role == ObjectRole::kWall) walls.push_back(&o);
      if (o.role != ObjectRole::kWindow) continue;
      EXPECT_EQ(o.rfs_class, kWindow);
      EXPECT_EQ(o.category, "window");
      if (IsWindowPane(o)) {
        panes.push_back(&o);
        glass += o.family == kWindowGlassFamily;
        blinds += o.family == kWindowBlindsFamily;
      } else {
        EXPECT_EQ(o.family, "window");
        window_frames.push_back(&o);
      }
    }
    ASSERT_EQ(panes.size(), window_frames.size()) << "seed " << seed;
    frames += static_cast<int>(window_frames.size());
    for (const PlacedObject* pane : panes) {
      const auto same_direction = [&](const PlacedObject* o) {
        return std::abs(std::remainder(o->yaw - pane->yaw, 2 * M_PI)) <= 1e-9;
      };
      EXPECT_NEAR(pane->scale.x(), 0.01, 1e-9);  // thickness, across the wall
      // Its wall: same orientation, nearest plane. The wall's box centre is mid-thickness, so
      // the pane's centre lies t/2 - inset - 0.005 in front of it along the inward normal.
      const Vec3 normal(std::cos(pane->yaw), std::sin(pane->yaw), 0.0);
      double best = 1e9;
      for (const PlacedObject* w : walls) {
        if (!same_direction(w)) continue;
        const double d = (pane->translation - w->translation).dot(normal);
        if (std::abs(d) < std::abs(best)) best = d;
      }
      const double t = cfg.wall_thickness;
      EXPECT_GE(best, t / 2 - 0.07 - 0.005 - 1e-9) << "seed " << seed;
      EXPECT_LE(best, t / 2 - 0.01 - 0.005 + 1e-9) << "seed " << seed;
      // Inside one frame: same wall direction, centred in the opening, 6 cm jambs on each side
      // and at the head, the sill's 6 cm below.
      const Vec3 along(-std::sin(pane->yaw), std::cos(pane->yaw), 0.0);
      int inside = 0;
      for (const PlacedObject* f : window_frames) {
        if (!same_direction(f)) continue;
        const double ds = (pane->translation - f->translation).dot(along);
        if (std::abs(ds) > 1e-6) continue;
        EXPECT_NEAR(pane->scale.y(), f->scale.y() - 0.12, 1e-6);
        EXPECT_NEAR(pane->scale.z(), f->scale.z() - 0.12, 1e-6);
        ++inside;
      }
      EXPECT_EQ(inside, 1) << "seed " << seed;
    }
  }
  EXPECT_GE(frames, 8);
  EXPECT_GT(glass, 0);
  EXPECT_GT(blinds, 0);
  // Off (the default): no panes.
  for (std::uint64_t seed = 0; seed < 4; ++seed) {
    for (const auto& o : ComposeRoom(RoomConfig(), seed).objects)
      EXPECT_EQ(o.family.rfind("window_", 0), std::string::npos);
  }
}

// RoomConfig::door_closed: all leaves closed at 1 (the door object is no deeper than its frame,
// wall thickness + 2 cm), all open at 0 (the leaf swings >= 0.4 rad into the room).
TEST(RoomDoorTest, DoorClosedClosesTheLeaves) {
  RoomConfig closed, open;
  closed.door_closed = 1.0;
  open.door_closed = 0.0;
  int doors_closed = 0, doors_open = 0;
  for (std::uint64_t seed = 0; seed < 12; ++seed) {
    for (const auto& x : ComposeRoom(closed, seed).objects) {
      if (x.role != ObjectRole::kDoor) continue;
      ++doors_closed;
      EXPECT_NEAR(x.scale.x(), closed.wall_thickness + 0.02, 1e-6) << "seed " << seed;
    }
    for (const auto& y : ComposeRoom(open, seed).objects) {
      if (y.role != ObjectRole::kDoor) continue;
      ++doors_open;
      EXPECT_GT(y.scale.x(), open.wall_thickness + 0.02 + 0.2) << "seed " << seed;
    }
  }
  EXPECT_GE(doors_closed, 12);
  EXPECT_GE(doors_open, 12);
}

// RoomConfig::studio: with probability 1 every room is a studio apartment - a sofa group and two
// or more cabinets in each, bookshelves in most (a wall may be full), more objects in all than
// the plain rooms of the same seeds; with 0 the rooms are the default ones (no draw).
TEST(RoomStudioTest, StudiosHoldTheZonesOfAFlatInOneRoom) {
  RoomConfig studio;
  studio.studio = 1.0;
  std::size_t studio_objects = 0, plain_objects = 0;
  int with_bookshelf = 0;
  for (std::uint64_t seed = 0; seed < 8; ++seed) {
    const Room s = ComposeRoom(studio, seed);
    EXPECT_EQ(s.room_type, "studio") << "seed " << seed;
    int sofas = 0, cabinets = 0, bookshelves = 0;
    for (const auto& o : s.objects) {
      sofas += o.cad_class == kCadSofa;
      cabinets += o.cad_class == kCadCabinet;
      bookshelves += o.cad_class == kCadBookshelf;
    }
    EXPECT_GE(sofas, 1) << "seed " << seed;
    EXPECT_GE(cabinets, 2) << "seed " << seed;
    with_bookshelf += bookshelves > 0;
    const Room plain = ComposeRoom(RoomConfig(), seed);
    EXPECT_NE(plain.room_type, "studio");
    studio_objects += s.objects.size();
    plain_objects += plain.objects.size();
    RoomConfig off;
    off.studio = 0.0;
    const Room same = ComposeRoom(off, seed);
    ASSERT_EQ(same.objects.size(), plain.objects.size());
    EXPECT_EQ(same.room_type, plain.room_type);
  }
  EXPECT_GE(with_bookshelf, 6);
  EXPECT_GT(studio_objects, plain_objects);
}

// Validate() throws InvalidArgument whose message names `field`.
void ExpectRejectedNaming(const RoomConfig& c, const std::string& field) {
  try {
    c.Validate();
    ADD_FAILURE() << field << " accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(RoomConfigTest, RejectsBadValues) {
  RoomConfig c;
  c.min_objects = 10;
  c.max_objects = 5;
  EXPECT_THROW(ComposeRoom(c, 0), InvalidArgument);
  c = RoomConfig();
  c.wall_thickness = 0;
  ExpectRejectedNaming(c, "wall_thickness");
  c = RoomConfig();
  c.window_pane = 1.5;
  ExpectRejectedNaming(c, "window_pane");
  c = RoomConfig();
  c.door_closed = -0.1;
  ExpectRejectedNaming(c, "door_closed");
  c = RoomConfig();
  c.studio = 2;
  ExpectRejectedNaming(c, "studio");
  EXPECT_THROW(CadSizeRange(8, nullptr, nullptr), InvalidArgument);
}

}  // namespace
}  // namespace dimr::data
