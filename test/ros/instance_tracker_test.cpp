// Stable instance ids: the association rule of instance_tracker.h on synthetic box sets.
#include "dimr/ros/instance_tracker.h"

#include <gtest/gtest.h>

#include <random>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

TrackInput Box(int cls, double x, double y, double sx = 1.0, double heading = 0.0) {
  TrackInput t;
  t.cad_class = cls;
  t.box.center = geometry::Vec3(x, y, 0.4);
  t.box.size = geometry::Vec3(sx, 0.6, 0.8);
  t.box.heading = heading;
  return t;
}

TEST(InstanceTracker, FreshIdsThenSameIdsForTheSameScene) {
  InstanceTracker tr;
  const std::vector<TrackInput> scene = {Box(0, 0, 0), Box(1, 3, 0), Box(1, 3, 2)};
  const TrackResult a = tr.Update(scene);
  EXPECT_EQ(a.ids, (std::vector<std::uint32_t>{1, 2, 3}));
  EXPECT_EQ(a.matched, 0);
  // Same scene in another order: ids follow the objects, not the order.
  const TrackResult b = tr.Update({scene[2], scene[0], scene[1]});
  EXPECT_EQ(b.ids, (std::vector<std::uint32_t>{3, 1, 2}));
  EXPECT_EQ(b.matched, 3);
  EXPECT_TRUE(b.removed.empty());
  EXPECT_EQ(b.revisions, (std::vector<std::uint32_t>{0, 0, 0}));  // unchanged
}

TEST(InstanceTracker, StableUnderNoiseOverManyUpdates) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 0.03);  // 3 cm / 0.03 rad noise
  std::vector<TrackInput> truth;
  for (int i = 0; i < 12; ++i) truth.push_back(Box(i % 8, 1.5 * (i % 4), 1.5 * (i / 4)));
  InstanceTracker tr;
  const TrackResult first = tr.Update(truth);
  for (int round = 0; round < 20; ++round) {
    std::vector<TrackInput> noisy = truth;
    for (TrackInput& t : noisy) {
      t.box.center += geometry::Vec3(n(rng), n(rng), n(rng));
      t.box.size += geometry::Vec3(n(rng), n(rng), n(rng));
      t.box.heading += n(rng);
    }
    std::shuffle(noisy.begin(), noisy.end(), rng);
    const TrackResult r = tr.Update(noisy);
    ASSERT_EQ(r.matched, 12);
    for (std::size_t k = 0; k < noisy.size(); ++k) {
      // Find which truth box this is (unique by position) and check its id.
      std::size_t t = 0;
      for (std::size_t j = 0; j < truth.size(); ++j)
        if ((truth[j].box.center - noisy[k].box.center).norm() < 0.5) t = j;
      EXPECT_EQ(r.ids[k], first.ids[t]);
      EXPECT_EQ(r.revisions[k], static_cast<std::uint32_t>(round + 1));  // moved every round
    }
  }
  EXPECT_EQ(tr.next_id(), 13u);
}

TEST(InstanceTracker, ClassMustAgree) {
  InstanceTracker tr;
  tr.Update({Box(1, 0, 0)});
  const TrackResult r = tr.Update({Box(2, 0, 0)});  // same place, other class
  EXPECT_EQ(r.ids, (std::vector<std::uint32_t>{2}));
  EXPECT_EQ(r.removed, (std::vector<std::uint32_t>{1}));
}

TEST(InstanceTracker, OverlapOrCentreDistanceMatches) {
  AssociationConfig c;
  c.min_iou = 0.5;
  c.max_center_distance = 0.2;
  InstanceTracker tr(c);
  tr.Update({Box(0, 0, 0), Box(0, 5, 0)});
  // First: shifted 0.3 m along a 1 m box -> IoU 0.54 >= 0.5 (centre 0.3 > 0.2). Second: a
  // small box inside the old one, centre 0.15 away -> IoU 0.25 but centre distance matches.
  const TrackResult r = tr.Update({Box(0, 0.3, 0), Box(0, 5.15, 0, 0.25)});
  EXPECT_EQ(r.ids, (std::vector<std::uint32_t>{1, 2}));
  // Too far for both criteria: new id.
  const TrackResult s = tr.Update({Box(0, 1.5, 0), Box(0, 5.15, 0, 0.25)});
  EXPECT_EQ(s.ids, (std::vector<std::uint32_t>{3, 2}));
  EXPECT_EQ(s.removed, (std::vector<std::uint32_t>{1}));
}

TEST(InstanceTracker, GreedyByIouEachTrackOnce) {
  InstanceTracker tr;
  tr.Update({Box(0, 0, 0)});
  // Two candidates for track 1: the better overlap keeps the id, the other gets a new one.
  const TrackResult r = tr.Update({Box(0, 0.25, 0), Box(0, 0.05, 0)});
  EXPECT_EQ(r.ids, (std::vector<std::uint32_t>{2, 1}));
  EXPECT_EQ(r.matched, 1);
}

TEST(InstanceTracker, VanishedIdsReportedAndNeverReused) {
  InstanceTracker tr;
  tr.Update({Box(0, 0, 0), Box(1, 3, 0), Box(2, 6, 0)});
  const TrackResult r = tr.Update({Box(1, 3, 0)});
  EXPECT_EQ(r.ids, (std::vector<std::uint32_t>{2}));
  EXPECT_EQ(r.removed, (std::vector<std::uint32_t>{1, 3}));
  const TrackResult back = tr.Update({Box(0, 0, 0), Box(1, 3, 0)});
  EXPECT_EQ(back.ids, (std::vector<std::uint32_t>{4, 2}));
  tr.Reset();
  EXPECT_EQ(tr.size(), 0u);
  EXPECT_EQ(tr.Update({Box(1, 3, 0)}).ids, (std::vector<std::uint32_t>{5}));
}

TEST(InstanceTracker, ContentChangeBumpsRevision) {
  InstanceTracker tr;
  TrackInput a = Box(3, 1, 1);
  a.content_hash = 11;
  tr.Update({a});
  EXPECT_EQ(tr.Update({a}).revisions[0], 0u);
  a.content_hash = 12;
  EXPECT_EQ(tr.Update({a}).revisions[0], 1u);
  a.box.heading += 2 * M_PI;  // same orientation
  EXPECT_EQ(tr.Update({a}).revisions[0], 1u);
}

TEST(InstanceTracker, InvalidConfigRejected) {
  AssociationConfig c;
  c.min_iou = 0;
  EXPECT_THROW(InstanceTracker{c}, InvalidArgument);
}

}  // namespace
}  // namespace dimr::ros1
