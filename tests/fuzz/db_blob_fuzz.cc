// The route database's blobs and rows as a damaged file would hold them, read through the code
// that build-db, localize and the retrieval index run: keypoints, descriptors, global descriptors,
// the retrieval model (ReadRetrievalModel, then GlobalDescriptorModel::Deserialize and Compute)
// and the 3-D points a frame sees. The database is built once from a fixed template; each input
// picks a target and supplies the declared sizes and the bytes, which a raw connection writes past
// the schema's CHECK constraints, as a corrupted file would hold them. So the fuzzer reaches the
// decoders at once instead of having to produce an SQLite file first.
//
// Input: byte 0 picks the target (mod 5), then the target's fields (below) in order; the rest
// of the input is the blob. Fields past the end of the input read as zero.
#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/core/error.h"
#include "epiloc/db/database.h"
#include "epiloc/retrieval/global_descriptor.h"
#include "fuzz_util.h"

namespace {

// Fields of the fuzz input, read in order, little-endian.
class Input {
 public:
  Input(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  uint8_t Byte() { return position_ < size_ ? data_[position_++] : 0; }
  uint32_t U32() {
    uint32_t value = 0;
    for (int b = 0; b < 4; ++b) value |= static_cast<uint32_t>(Byte()) << (8 * b);
    return value;
  }
  int64_t I64() {
    uint64_t value = U32();
    value |= static_cast<uint64_t>(U32()) << 32;
    return static_cast<int64_t>(value);
  }
  float F32() {
    const uint32_t bits = U32();
    float value;
    std::memcpy(&value, &bits, sizeof(value));
    return value;
  }
  double F64() {
    const uint64_t bits = static_cast<uint64_t>(I64());
    double value;
    std::memcpy(&value, &bits, sizeof(value));
    return value;
  }
  // The bytes not read yet.
  std::vector<uint8_t> Rest() {
    std::vector<uint8_t> rest(data_ + position_, data_ + size_);
    position_ = size_;
    return rest;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t position_ = 0;
};

// A finding: the harness stops the process so libFuzzer saves the input.
[[noreturn]] void Fail(const char* what) {
  std::fprintf(stderr, "db_blob_fuzz: %s\n", what);
  std::abort();
}

void PutU32(uint32_t value, std::vector<uint8_t>* bytes) {
  for (int b = 0; b < 4; ++b) bytes->push_back(static_cast<uint8_t>(value >> (8 * b)));
}

void PutF32(float value, std::vector<uint8_t>* bytes) {
  uint32_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  PutU32(bits, bytes);
}

float LittleEndianFloat(const uint8_t* bytes) {
  uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(bytes[b]) << (8 * b);
  float value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

// The smallest valid retrieval model blob (db_schema/README.md): one word, one dimension.
std::vector<uint8_t> TemplateModel() {
  std::vector<uint8_t> bytes = {'E', 'G', 'D', 'M'};
  PutU32(1, &bytes);     // version
  PutU32(1, &bytes);     // num_words
  PutU32(1, &bytes);     // dims
  PutU32(100, &bytes);   // features per image
  PutF32(0.1f, &bytes);  // whitening epsilon
  for (int i = 0; i < 128 + 128 + 1 + 128; ++i) PutF32(i == 256 ? 1.0f : 0.01f, &bytes);
  return bytes;
}

// The template database: a camera, a drive, two frames of two features each with their global
// descriptors, the retrieval model and one 3-D point both frames see; a raw connection writes
// past the schema's CHECKs, a read-only Database reads as localize does.
struct Fixture {
  std::string path;
  sqlite3* raw = nullptr;
  std::unique_ptr<epiloc::Database> db;
  epiloc::image_t image_id[2] = {epiloc::kInvalidImage, epiloc::kInvalidImage};
  int64_t point_id = -1;

  Fixture() {
    path = (epiloc::fuzz::ScratchDir() / "blobs.sqlite").string();
    for (const char* suffix : {"", "-wal", "-shm"}) std::remove((path + suffix).c_str());
    {
      epiloc::Database db(path);
      epiloc::DbCamera camera;
      camera.camera.width = 64;
      camera.camera.height = 48;
      camera.camera.fx = camera.camera.fy = 50;
      camera.camera.cx = 32;
      camera.camera.cy = 24;
      camera.original = camera.camera;
      epiloc::DbDrive drive;
      drive.name = "fuzz";
      drive.camera_id = db.WriteCamera(camera);
      drive.positions = "gnss";
      drive.drive_id = db.WriteDrive(drive);
      for (int i = 0; i < 2; ++i) {
        epiloc::DbFrame frame;
        frame.drive_id = drive.drive_id;
        frame.frame = i;
        frame.image_hash = std::to_string(i);
        frame.position = {49.0, 8.4, 110.0};
        image_id[i] = db.WriteFrame(frame, epiloc::FeatureKeypoints::Ones(2, 4),
                                    epiloc::FeatureDescriptors::Ones(2, 128));
        db.WriteGlobalDescriptor(image_id[i], {1.0f});
      }
      db.WriteRetrievalModel(TemplateModel(), 1, 1);
      epiloc::DbPoint3d point;
      point.position_in_enu = {1.0, 2.0, 3.0};
      point_id = db.WritePoint(point, {{image_id[0], 0}, {image_id[1], 1}});
    }
    if (sqlite3_open(path.c_str(), &raw) != SQLITE_OK) Fail("cannot open the template database");
    Exec("PRAGMA ignore_check_constraints = ON");
    Exec("PRAGMA synchronous = OFF");
    db = std::make_unique<epiloc::Database>(path, epiloc::Database::Mode::kReadOnly);
  }

  ~Fixture() {
    db.reset();
    sqlite3_close(raw);
  }
  Fixture(const Fixture&) = delete;
  Fixture& operator=(const Fixture&) = delete;

  void Exec(const char* sql) const { sqlite3_exec(raw, sql, nullptr, nullptr, nullptr); }
};

// Runs `sql` on the raw connection with `values` bound in order (int64, double or blob).
struct Value {
  enum { kInt, kReal, kBlob } type;
  int64_t i = 0;
  double d = 0.0;
  const std::vector<uint8_t>* blob = nullptr;
};

void Write(const Fixture& fixture, const char* sql, const std::vector<Value>& values) {
  sqlite3_stmt* stmt = nullptr;
  if (sqlite3_prepare_v2(fixture.raw, sql, -1, &stmt, nullptr) != SQLITE_OK) Fail(sql);
  for (size_t k = 0; k < values.size(); ++k) {
    const Value& v = values[k];
    const int at = static_cast<int>(k) + 1;
    if (v.type == Value::kInt) sqlite3_bind_int64(stmt, at, v.i);
    if (v.type == Value::kReal) sqlite3_bind_double(stmt, at, v.d);
    if (v.type == Value::kBlob) {
      // A zero-length blob, not NULL, for an empty vector.
      sqlite3_bind_blob(stmt, at, v.blob->empty() ? "" : static_cast<const void*>(v.blob->data()),
                        static_cast<int>(v.blob->size()), SQLITE_TRANSIENT);
    }
  }
  sqlite3_step(stmt);  // may fail (NOT NULL, a NaN bound as NULL): the row keeps its old values
  sqlite3_finalize(stmt);
}

Value Int(int64_t i) { return {Value::kInt, i, 0.0, nullptr}; }
Value Real(double d) { return {Value::kReal, 0, d, nullptr}; }
Value Blob(const std::vector<uint8_t>& blob) { return {Value::kBlob, 0, 0.0, &blob}; }

// Fields: rows (int32), cols (int32), then the blob. A blob read back must hold exactly the
// stored values.
void Keypoints(const Fixture& fixture, Input& input) {
  const int32_t rows = static_cast<int32_t>(input.U32());
  const int32_t cols = static_cast<int32_t>(input.U32());
  const std::vector<uint8_t> blob = input.Rest();
  Write(fixture, "UPDATE keypoints SET rows = ?, cols = ?, data = ? WHERE image_id = ?",
        {Int(rows), Int(cols), Blob(blob), Int(fixture.image_id[0])});
  const epiloc::FeatureKeypoints keypoints = fixture.db->ReadKeypoints(fixture.image_id[0]);
  if (static_cast<size_t>(keypoints.size()) * 4 != blob.size()) Fail("keypoints: wrong size");
  for (Eigen::Index r = 0; r < keypoints.rows(); ++r) {
    for (Eigen::Index c = 0; c < keypoints.cols(); ++c) {
      const float stored = LittleEndianFloat(&blob[4 * (4 * r + c)]);
      if (std::memcmp(&stored, &keypoints(r, c), 4) != 0) Fail("keypoints: wrong value");
    }
  }
}

void Descriptors(const Fixture& fixture, Input& input) {
  const int32_t rows = static_cast<int32_t>(input.U32());
  const int32_t cols = static_cast<int32_t>(input.U32());
  const std::vector<uint8_t> blob = input.Rest();
  Write(fixture, "UPDATE descriptors SET rows = ?, cols = ?, data = ? WHERE image_id = ?",
        {Int(rows), Int(cols), Blob(blob), Int(fixture.image_id[1])});
  const epiloc::FeatureDescriptors descriptors = fixture.db->ReadDescriptors(fixture.image_id[1]);
  if (static_cast<size_t>(descriptors.size()) != blob.size()) Fail("descriptors: wrong size");
  for (Eigen::Index r = 0; r < descriptors.rows(); ++r) {
    if (std::memcmp(descriptors.row(r).data(), &blob[128 * r], 128) != 0) {
      Fail("descriptors: wrong value");
    }
  }
}

// Fields: dims (int64), then the blob of the second frame's global descriptor.
void GlobalDescriptors(const Fixture& fixture, Input& input) {
  const int64_t dims = input.I64();
  const std::vector<uint8_t> blob = input.Rest();
  Write(fixture, "UPDATE global_descriptors SET dims = ?, data = ? WHERE image_id = ?",
        {Int(dims), Blob(blob), Int(fixture.image_id[1])});
  const auto descriptors = fixture.db->ReadGlobalDescriptors();
  if (descriptors.size() != 2) Fail("global descriptors: wrong count");
  const std::vector<float>& values = descriptors[1].second;
  if (values.size() * 4 != blob.size()) Fail("global descriptors: wrong size");
  for (size_t i = 0; i < values.size(); ++i) {
    const float stored = LittleEndianFloat(&blob[4 * i]);
    if (std::memcmp(&stored, &values[i], 4) != 0) Fail("global descriptors: wrong value");
  }
}

// Fields: flags (bit 0: the rest is the whole blob as is; bit 1: a bad magic; bit 2: the
// version from the input), version (uint32), num_words (1 + byte % 3), dims (1 + byte % 8),
// features per image (uint32), whitening epsilon (float), size change (int8), query rows
// (byte % 4). Unless bit 0, the model's values repeat the rest of the input (zeros without one)
// and the blob has the size its header declares plus the size change, so the decoder's checks
// of the values are reached. A model that decodes is serialized back to the same bytes and
// computes a descriptor of dims() values for query descriptors taken from the input.
void Model(const Fixture& fixture, Input& input) {
  const uint8_t flags = input.Byte();
  const uint32_t version = input.U32();
  const uint32_t num_words = 1 + input.Byte() % 3;
  const uint32_t dims = 1 + input.Byte() % 8;
  const uint32_t features = input.U32();
  const float epsilon = input.F32();
  const int8_t size_change = static_cast<int8_t>(input.Byte());
  const int query_rows = input.Byte() % 4;
  std::vector<uint8_t> query(static_cast<size_t>(query_rows) * 128);
  for (uint8_t& q : query) q = input.Byte();
  const std::vector<uint8_t> rest = input.Rest();
  std::vector<uint8_t> blob;
  if (flags & 1) {
    blob = rest;
  } else {
    blob = {'E', 'G', 'D', static_cast<uint8_t>(flags & 2 ? 'X' : 'M')};
    PutU32(flags & 4 ? version : 1, &blob);
    PutU32(num_words, &blob);
    PutU32(dims, &blob);
    PutU32(features, &blob);
    PutF32(epsilon, &blob);
    const size_t vlad = 128 * num_words;
    const size_t values = vlad + vlad + dims + dims * vlad;
    for (size_t i = 0; i < 4 * values; ++i)
      blob.push_back(rest.empty() ? 0 : rest[i % rest.size()]);
    if (size_change < 0) blob.resize(blob.size() - static_cast<size_t>(-size_change));
    for (int8_t i = 0; i < size_change; ++i) blob.push_back(0);
  }
  Write(fixture, "UPDATE retrieval_model SET data = ? WHERE id = 1", {Blob(blob)});
  const std::optional<std::vector<uint8_t>> bytes = fixture.db->ReadRetrievalModel();
  if (!bytes || *bytes != blob) Fail("retrieval model: read back differs");
  const epiloc::GlobalDescriptorModel model = epiloc::GlobalDescriptorModel::Deserialize(*bytes);
  if (model.Serialize() != blob) Fail("retrieval model: serialized back differs");
  epiloc::FeatureDescriptors descriptors(query_rows, 128);
  if (query_rows > 0) std::memcpy(descriptors.data(), query.data(), query.size());
  if (model.Compute(descriptors).size() != model.dims()) Fail("retrieval model: wrong dims");
}

// Fields: feature index (int64) of the first frame's observation, the point's position (3
// doubles, metres). Every point read back names a feature row (index >= 0) and has a finite
// position (the writer accepts no other).
void FramePoints(const Fixture& fixture, Input& input) {
  const int64_t feature_index = input.I64();
  const double e = input.F64(), n = input.F64(), u = input.F64();
  Write(fixture, "UPDATE observations SET feature_index = ? WHERE image_id = ? AND point_id = ?",
        {Int(feature_index), Int(fixture.image_id[0]), Int(fixture.point_id)});
  Write(fixture, "UPDATE points3d SET e_m = ?, n_m = ?, u_m = ? WHERE point_id = ?",
        {Real(e), Real(n), Real(u), Int(fixture.point_id)});
  for (const epiloc::DbFramePoint& point : fixture.db->ReadFramePoints(fixture.image_id[0])) {
    if (point.feature_index < 0) Fail("frame points: negative feature index");
    if (!point.position_in_enu.allFinite()) Fail("frame points: non-finite position");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Fixture fixture;
  Input input(data, size);
  try {
    switch (input.Byte() % 5) {
      case 0:
        Model(fixture, input);
        break;
      case 1:
        Keypoints(fixture, input);
        break;
      case 2:
        Descriptors(fixture, input);
        break;
      case 3:
        GlobalDescriptors(fixture, input);
        break;
      default:
        FramePoints(fixture, input);
        break;
    }
  } catch (const epiloc::Error&) {
  }
  return 0;
}
