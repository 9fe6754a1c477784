#include "epiloc/io/stella_map.h"

#include <cmath>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "stella_map_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

Rigid3d Pose(double yaw, const Eigen::Vector3d& centre) {
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY())), centre);
}

// Three keyframes saved out of time order (stella keys them by id), four landmarks: one seen from
// keyframes 7 and 3, one from all three, one from none (left out), and one a keyframe names but
// the map does not hold (erased: skipped).
std::vector<TestStellaKeyframe> Keyframes() {
  return {{7, 12.5, Pose(0.2, {1.0, 0.1, 4.0}), {-1, 10, 11, -1, 99}},
          {3, 11.0, Pose(0.0, {0.0, 0.0, 0.0}), {10, -1, 11, 11}},
          {5, 11.7, Pose(0.1, {0.4, 0.05, 2.0}), {11}}};
}

std::vector<TestStellaLandmark> Landmarks() {
  return {{10, {1.0, -1.0, 10.0}}, {11, {-2.0, 0.5, 12.0}}, {12, {0.0, 0.0, 9.0}}};
}

TEST(StellaMap, ReadsKeyframesInTimeOrderAndWhoObservesEachLandmark) {
  TempDir dir;
  const std::string path = dir / "map.msg";
  WriteMessagePack(StellaMapJson(Keyframes(), Landmarks()), path);
  EXPECT_TRUE(IsMessagePackFile(path));
  const StellaMap map = ReadStellaMap(path);
  ASSERT_EQ(map.keyframes.size(), 3u);
  EXPECT_EQ(map.keyframe_ids, (std::vector<int64_t>{3, 5, 7}));
  const std::vector<TestStellaKeyframe> written = Keyframes();
  const std::vector<size_t> order = {1, 2, 0};  // ids 3, 5, 7
  for (size_t i = 0; i < 3; ++i) {
    const TestStellaKeyframe& k = written[order[i]];
    EXPECT_EQ(map.keyframes[i].timestamp_s, k.timestamp_s);
    EXPECT_EQ(map.keyframes[i].frame, kInvalidFrame);
    EXPECT_LT((map.keyframes[i].world_from_cam.translation - k.world_from_cam.translation).norm(),
              1e-12);
    EXPECT_LT(RotationDifferenceDeg(map.keyframes[i].world_from_cam.rotation,
                                    k.world_from_cam.rotation),
              1e-9);
  }
  ASSERT_EQ(map.landmarks.size(), 2u);
  EXPECT_EQ(map.landmarks[0].id, 10);
  EXPECT_EQ(map.landmarks[0].keyframes, (std::vector<int>{0, 2}));
  EXPECT_EQ(map.landmarks[0].position_in_world, Eigen::Vector3d(1.0, -1.0, 10.0));
  EXPECT_EQ(map.landmarks[1].id, 11);
  EXPECT_EQ(map.landmarks[1].keyframes, (std::vector<int>{0, 1, 2}));  // twice in keyframe 3: once
}

TEST(StellaMap, TextFilesAreNotMessagePack) {
  TempDir dir;
  WriteText(dir / "traj.txt", "0.0 0 0 0 0 0 0 1\n");
  EXPECT_FALSE(IsMessagePackFile(dir / "traj.txt"));
  EXPECT_FALSE(IsMessagePackFile(dir / "missing.msg"));
}

TEST(StellaMap, BadInputIsAnErrorNamingTheFileAndTheField) {
  TempDir dir;
  const std::string path = dir / "map.msg";
  const auto expect = [&](const nlohmann::json& json, const std::vector<std::string>& parts) {
    WriteMessagePack(json, path);
    std::vector<std::string> with_path = parts;
    with_path.push_back(path);
    ExpectError([&] { ReadStellaMap(path); }, with_path);
  };
  const nlohmann::json good = StellaMapJson(Keyframes(), Landmarks());
  {
    nlohmann::json j = good;
    j.erase("keyframes");
    expect(j, {"no 'keyframes' object"});
  }
  {
    nlohmann::json j = good;
    j["keyframes"]["5"].erase("rot_cw");
    expect(j, {"keyframe 5 has no 'rot_cw'"});
  }
  {
    nlohmann::json j = good;
    j["keyframes"]["5"]["rot_cw"] = {0.0, 0.0, 0.0, 2.0};
    expect(j, {"keyframe 5", "not a unit quaternion"});
  }
  {
    nlohmann::json j = good;
    j["keyframes"]["5"]["trans_cw"] = {0.0, "x", 0.0};
    expect(j, {"keyframe 5", "'trans_cw'", "non-numeric"});
  }
  {
    nlohmann::json j = good;
    j["keyframes"]["5"]["ts"] = 12.5;
    expect(j, {"keyframes 5 and 7 have the same time"});
  }
  {
    nlohmann::json j = good;
    j["landmarks"]["11"]["pos_w"] = {1.0, 2.0};
    expect(j, {"landmark 11", "'pos_w' is not an array of 3 numbers"});
  }
  {
    nlohmann::json j = good;
    j["keyframes"]["x1"] = j["keyframes"]["5"];
    expect(j, {"keyframe id 'x1' is not an integer"});
  }
  {
    nlohmann::json j = good;
    j["keyframes"] = nlohmann::json::object();
    expect(j, {"no keyframes"});
  }
  WriteText(path, std::string("SQLite format 3") + '\0' + "rest of the database");
  ExpectError([&] { ReadStellaMap(path); }, {path, "SQLite map database", "msgpack"});
  WriteText(path, "\x86\xa7");  // a map of 6 entries, cut after one byte of its first key
  ExpectError([&] { ReadStellaMap(path); }, {path, "not a MessagePack map database"});
  ExpectError([&] { ReadStellaMap(dir / "missing.msg"); }, {"missing.msg", "cannot open"});
  // A million nested arrays: refused before the (recursive) MessagePack reader sees them.
  WriteText(path, std::string(1000000, '\x91') + '\xc0');
  ExpectError([&] { ReadStellaMap(path); }, {path, "nested 1000000 levels deep"});
  // An array that claims more values than the file has bytes.
  WriteText(path, "\xdd\x7f\xff\xff\xff\x01");
  ExpectError([&] { ReadStellaMap(path); }, {path, "malformed or truncated"});
}

}  // namespace
}  // namespace epiloc
