// Writes a stella_vslam map database in its MessagePack format (the fields io/stella_map.h reads,
// laid out as stella_vslam's map_database_io_msgpack saves them, plus some it does not read), for
// tests of the readers. Header-only; the test links nlohmann_json.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "epiloc/geo/rigid3.h"

namespace epiloc {

struct TestStellaKeyframe {
  int64_t id = 0;
  double timestamp_s = 0.0;
  Rigid3d world_from_cam;
  std::vector<int64_t> landmark_ids;  // per keypoint, -1: none
};

struct TestStellaLandmark {
  int64_t id = 0;
  Eigen::Vector3d position_in_world = Eigen::Vector3d::Zero();
};

inline nlohmann::json StellaMapJson(const std::vector<TestStellaKeyframe>& keyframes,
                                    const std::vector<TestStellaLandmark>& landmarks) {
  nlohmann::json kfs = nlohmann::json::object();
  for (const TestStellaKeyframe& k : keyframes) {
    const Rigid3d cam_from_world = k.world_from_cam.Inverse();
    const Eigen::Quaterniond& q = cam_from_world.rotation;
    const Eigen::Vector3d& t = cam_from_world.translation;
    kfs[std::to_string(k.id)] = {{"ts", k.timestamp_s},
                                 {"cam", "test camera"},
                                 {"orb_params", "default"},
                                 {"rot_cw", {q.x(), q.y(), q.z(), q.w()}},
                                 {"trans_cw", {t.x(), t.y(), t.z()}},
                                 {"n_keypts", k.landmark_ids.size()},
                                 {"lm_ids", k.landmark_ids},
                                 {"span_parent", -1},
                                 {"span_children", nlohmann::json::array()},
                                 {"loop_edges", nlohmann::json::array()}};
  }
  nlohmann::json lms = nlohmann::json::object();
  for (const TestStellaLandmark& l : landmarks) {
    const Eigen::Vector3d& p = l.position_in_world;
    lms[std::to_string(l.id)] = {{"1st_keyfrm", keyframes.empty() ? 0 : keyframes.front().id},
                                 {"pos_w", {p.x(), p.y(), p.z()}},
                                 {"ref_keyfrm", keyframes.empty() ? 0 : keyframes.front().id},
                                 {"n_vis", 2},
                                 {"n_fnd", 2}};
  }
  return {{"cameras", nlohmann::json::object()},
          {"orb_params", nlohmann::json::object()},
          {"keyframes", kfs},
          {"landmarks", lms},
          {"keyframe_next_id", keyframes.size()},
          {"landmark_next_id", landmarks.size()}};
}

inline void WriteMessagePack(const nlohmann::json& json, const std::string& path) {
  const std::vector<uint8_t> bytes = nlohmann::json::to_msgpack(json);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace epiloc
