// Blobs of the route database as a damaged file would hold them: keypoints, descriptors and global
// descriptors (rows, cols and bytes that disagree, written past the schema's CHECKs) read through
// Database, and the retrieval model blob through its deserializer.
#include <sqlite3.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "epiloc/core/error.h"
#include "epiloc/db/database.h"
#include "epiloc/retrieval/global_descriptor.h"
#include "fuzz_util.h"

namespace {

// A database with one frame (two features) and its global descriptor, and a raw connection that
// writes past the schema's CHECK constraints, as a corrupted file would.
struct Fixture {
  std::string path;
  sqlite3* raw = nullptr;
  epiloc::image_t image_id = epiloc::kInvalidImage;

  Fixture() {
    path = (epiloc::fuzz::ScratchDir() / "blobs.sqlite").string();
    std::remove(path.c_str());
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
      epiloc::DbFrame frame;
      frame.drive_id = drive.drive_id;
      frame.frame = 0;
      frame.image_hash = "0";
      frame.position = {49.0, 8.4, 110.0};
      frame.num_features = 2;
      epiloc::FeatureKeypoints keypoints = epiloc::FeatureKeypoints::Ones(2, 4);
      epiloc::FeatureDescriptors descriptors = epiloc::FeatureDescriptors::Ones(2, 128);
      image_id = db.WriteFrame(frame, keypoints, descriptors);
      db.WriteGlobalDescriptor(image_id, std::vector<float>(8, 0.5f));
    }
    sqlite3_open(path.c_str(), &raw);
    sqlite3_exec(raw, "PRAGMA ignore_check_constraints = ON", nullptr, nullptr, nullptr);
  }
};

void Update(sqlite3* raw, const char* sql, int64_t a, int64_t b, const uint8_t* data, size_t n,
            int64_t image_id) {
  sqlite3_stmt* stmt = nullptr;
  sqlite3_prepare_v2(raw, sql, -1, &stmt, nullptr);
  sqlite3_bind_int64(stmt, 1, a);
  sqlite3_bind_int64(stmt, 2, b);
  sqlite3_bind_blob(stmt, 3, n ? data : reinterpret_cast<const uint8_t*>(""), static_cast<int>(n),
                    SQLITE_TRANSIENT);
  sqlite3_bind_int64(stmt, 4, image_id);
  sqlite3_step(stmt);
  sqlite3_finalize(stmt);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Fixture fixture;
  if (size < 9) return 0;
  const int which = data[0] % 4;
  int32_t a = 0, b = 0;
  std::memcpy(&a, data + 1, 4);
  std::memcpy(&b, data + 5, 4);
  const uint8_t* blob = data + 9;
  const size_t n = size - 9;
  try {
    if (which == 0) {
      (void)epiloc::GlobalDescriptorModel::Deserialize(std::vector<uint8_t>(blob, blob + n));
      return 0;
    }
    if (which == 1) {
      Update(fixture.raw, "UPDATE keypoints SET rows = ?, cols = ?, data = ? WHERE image_id = ?",
             a, b, blob, n, fixture.image_id);
    } else if (which == 2) {
      Update(fixture.raw, "UPDATE descriptors SET rows = ?, cols = ?, data = ? WHERE image_id = ?",
             a, b, blob, n, fixture.image_id);
    } else {
      Update(fixture.raw,
             "UPDATE global_descriptors SET dims = ?, image_id = image_id + ? * 0, data = ? "
             "WHERE image_id = ?",
             a, b, blob, n, fixture.image_id);
    }
    const epiloc::Database db(fixture.path, epiloc::Database::Mode::kReadOnly);
    if (which == 1) (void)db.ReadKeypoints(fixture.image_id);
    if (which == 2) (void)db.ReadDescriptors(fixture.image_id);
    if (which == 3) (void)db.ReadGlobalDescriptors();
  } catch (const epiloc::Error&) {
  }
  return 0;
}
