#include "epiloc/io/stella_map.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using nlohmann::json;

// The id of a keyframe or landmark, from its key in the map's object.
int64_t ParseId(const std::string& path, const std::string& what, const std::string& key) {
  size_t used = 0;
  int64_t id = 0;
  try {
    id = std::stoll(key, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != key.size()) {
    Throw("{}: {} id '{}' is not an integer", path, what, Printable(key, 40));
  }
  return id;
}

// `count` finite numbers from the array `field` of `object` (`where`: "keyframe 3").
Eigen::VectorXd Numbers(const std::string& path,
                        const std::string& where,
                        const json& object,
                        const char* field,
                        int count) {
  const auto it = object.find(field);
  if (it == object.end()) Throw("{}: {} has no '{}'", path, where, field);
  if (!it->is_array() || static_cast<int>(it->size()) != count) {
    Throw("{}: {}: '{}' is not an array of {} numbers", path, where, field, count);
  }
  Eigen::VectorXd v(count);
  for (int i = 0; i < count; ++i) {
    const json& x = (*it)[i];
    if (!x.is_number() || !std::isfinite(x.get<double>())) {
      Throw("{}: {}: '{}' holds a non-finite or non-numeric value", path, where, field);
    }
    v[i] = x.get<double>();
  }
  return v;
}

// The finite number `field` of `object`.
double Number(const std::string& path, const std::string& where, const json& object,
              const char* field) {
  const auto it = object.find(field);
  if (it == object.end()) Throw("{}: {} has no '{}'", path, where, field);
  if (!it->is_number() || !std::isfinite(it->get<double>())) {
    Throw("{}: {}: '{}' is not a finite number", path, where, field);
  }
  return it->get<double>();
}

// The deepest nesting of arrays and maps in MessagePack `bytes`, walked without recursion (the
// library's MessagePack reader recurses once per level: a hostile file of a million nested
// arrays would overflow the stack); nullopt for a malformed or truncated value.
std::optional<int> MessagePackDepth(const std::vector<uint8_t>& bytes) {
  size_t at = 0;
  const auto read = [&](int n, uint64_t* value) {
    if (bytes.size() - at < static_cast<size_t>(n)) return false;
    *value = 0;
    for (int i = 0; i < n; ++i) *value = (*value << 8) | bytes[at++];
    return true;
  };
  const auto skip = [&](uint64_t n) {
    if (bytes.size() - at < n) return false;
    at += n;
    return true;
  };
  std::vector<uint64_t> open;  // values still to come in each open array or map
  int depth = 0;
  uint64_t to_read = 1;        // values at the top level
  while (true) {
    // Close the containers whose values are all read.
    while (to_read == 0) {
      if (open.empty()) return depth;
      to_read = open.back();
      open.pop_back();
    }
    if (at >= bytes.size()) return std::nullopt;
    const uint8_t type = bytes[at++];
    --to_read;
    uint64_t n = 0, children = 0;
    bool container = false;
    if (type <= 0x7f || type >= 0xe0 || type == 0xc0 || type == 0xc2 || type == 0xc3) {
    } else if (type <= 0x8f) {
      children = 2 * (type & 0x0f);
      container = true;
    } else if (type <= 0x9f) {
      children = type & 0x0f;
      container = true;
    } else if (type <= 0xbf) {
      if (!skip(type & 0x1f)) return std::nullopt;
    } else if (type >= 0xc4 && type <= 0xc6) {  // bin 8/16/32
      if (!read(1 << (type - 0xc4), &n) || !skip(n)) return std::nullopt;
    } else if (type >= 0xc7 && type <= 0xc9) {  // ext 8/16/32: size, type, data
      if (!read(1 << (type - 0xc7), &n) || !skip(n + 1)) return std::nullopt;
    } else if (type == 0xca || type == 0xcb) {  // float 32/64
      if (!skip(type == 0xca ? 4 : 8)) return std::nullopt;
    } else if (type >= 0xcc && type <= 0xd3) {  // (u)int 8-64
      if (!skip(1u << ((type - 0xcc) % 4))) return std::nullopt;
    } else if (type >= 0xd4 && type <= 0xd8) {  // fixext 1-16: type, data
      if (!skip(1 + (1u << (type - 0xd4)))) return std::nullopt;
    } else if (type >= 0xd9 && type <= 0xdb) {  // str 8/16/32
      if (!read(1 << (type - 0xd9), &n) || !skip(n)) return std::nullopt;
    } else if (type == 0xdc || type == 0xdd) {  // array 16/32
      if (!read(type == 0xdc ? 2 : 4, &n)) return std::nullopt;
      children = n;
      container = true;
    } else if (type == 0xde || type == 0xdf) {  // map 16/32
      if (!read(type == 0xde ? 2 : 4, &n)) return std::nullopt;
      children = 2 * n;
      container = true;
    } else {
      return std::nullopt;  // 0xc1: never used
    }
    if (container) {
      // Each value takes at least a byte: a count beyond the bytes left is malformed.
      if (children > bytes.size() - at) return std::nullopt;
      open.push_back(to_read);
      depth = std::max(depth, static_cast<int>(open.size()));
      to_read = children;
    }
  }
}

const json& ObjectField(const std::string& path, const json& root, const char* field) {
  const auto it = root.find(field);
  if (it == root.end() || !it->is_object()) {
    Throw("{}: no '{}' object (not a stella_vslam map database?)", path, field);
  }
  return *it;
}

}  // namespace

bool IsMessagePackFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const int first = in.get();
  // fixmap (0x80-0x8f), map 16 (0xde), map 32 (0xdf).
  return in && ((first >= 0x80 && first <= 0x8f) || first == 0xde || first == 0xdf);
}

StellaMap ReadStellaMap(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Throw("{}: cannot open the map database", path);
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  static const char kSqlite[] = "SQLite format 3";
  if (bytes.size() >= sizeof(kSqlite) && std::memcmp(bytes.data(), kSqlite, sizeof(kSqlite)) == 0) {
    Throw(
        "{}: an SQLite map database (stella_vslam's sqlite3 map format) is not read; save the map "
        "with the msgpack format",
        path);
  }
  // stella's map is 4 levels deep (root, keyframes, a keyframe, its keypoints' fields).
  constexpr int kMaxDepth = 32;
  const std::optional<int> depth = MessagePackDepth(bytes);
  if (!depth) Throw("{}: not a MessagePack map database (malformed or truncated)", path);
  if (*depth > kMaxDepth) {
    Throw("{}: not a stella_vslam map database (nested {} levels deep)", path, *depth);
  }
  json root;
  try {
    root = json::from_msgpack(bytes);
  } catch (const json::exception& e) {
    Throw("{}: not a MessagePack map database ({})", path, Printable(e.what(), 120));
  }
  if (!root.is_object()) Throw("{}: not a stella_vslam map database (no root object)", path);
  const json& keyframes = ObjectField(path, root, "keyframes");
  const json& landmarks = ObjectField(path, root, "landmarks");

  StellaMap map;
  // Landmarks by id.
  std::map<int64_t, StellaLandmark> by_id;
  for (auto it = landmarks.begin(); it != landmarks.end(); ++it) {
    StellaLandmark landmark;
    landmark.id = ParseId(path, "landmark", it.key());
    const std::string where = fmt::format("landmark {}", landmark.id);
    if (!it->is_object()) Throw("{}: {} is not an object", path, where);
    landmark.position_in_world = Numbers(path, where, *it, "pos_w", 3);
    by_id.emplace(landmark.id, std::move(landmark));
  }

  // Keyframes, then put in time order.
  struct Keyframe {
    int64_t id = 0;
    StampedPose pose;
    std::vector<int64_t> landmark_ids;
  };
  std::vector<Keyframe> read;
  for (auto it = keyframes.begin(); it != keyframes.end(); ++it) {
    Keyframe k;
    k.id = ParseId(path, "keyframe", it.key());
    const std::string where = fmt::format("keyframe {}", k.id);
    if (!it->is_object()) Throw("{}: {} is not an object", path, where);
    k.pose.timestamp_s = Number(path, where, *it, "ts");
    const Eigen::VectorXd q = Numbers(path, where, *it, "rot_cw", 4);
    const Eigen::Vector3d trans_cw = Numbers(path, where, *it, "trans_cw", 3);
    Eigen::Quaterniond cam_from_world(q[3], q[0], q[1], q[2]);
    const double norm = cam_from_world.norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      Throw("{}: {}: 'rot_cw' is not a unit quaternion (norm {})", path, where, norm);
    }
    cam_from_world.normalize();
    k.pose.world_from_cam = Rigid3d(cam_from_world, trans_cw).Inverse();
    const auto ids = it->find("lm_ids");
    if (ids == it->end()) Throw("{}: {} has no 'lm_ids'", path, where);
    if (!ids->is_array()) Throw("{}: {}: 'lm_ids' is not an array", path, where);
    for (const json& id : *ids) {
      if (!id.is_number_integer()) Throw("{}: {}: 'lm_ids' holds a non-integer", path, where);
      if (id.get<int64_t>() >= 0) k.landmark_ids.push_back(id.get<int64_t>());
    }
    read.push_back(std::move(k));
  }
  if (read.empty()) Throw("{}: the map has no keyframes", path);
  std::stable_sort(read.begin(), read.end(), [](const Keyframe& a, const Keyframe& b) {
    return a.pose.timestamp_s < b.pose.timestamp_s;
  });
  for (size_t i = 0; i < read.size(); ++i) {
    if (i > 0 && read[i].pose.timestamp_s == read[i - 1].pose.timestamp_s) {
      Throw("{}: keyframes {} and {} have the same time {}", path, read[i - 1].id, read[i].id,
            read[i].pose.timestamp_s);
    }
    map.keyframes.push_back(read[i].pose);
    map.keyframe_ids.push_back(read[i].id);
    // A landmark the keyframe names but the map does not hold was erased: skipped.
    for (const int64_t id : read[i].landmark_ids) {
      const auto found = by_id.find(id);
      if (found == by_id.end()) continue;
      std::vector<int>& observers = found->second.keyframes;
      if (observers.empty() || observers.back() != static_cast<int>(i)) {
        observers.push_back(static_cast<int>(i));
      }
    }
  }
  for (auto& [id, landmark] : by_id) {
    if (!landmark.keyframes.empty()) map.landmarks.push_back(std::move(landmark));
  }
  return map;
}

}  // namespace epiloc
