// Localizes a recorded drive frame by frame through epiloc's library API, as an in-vehicle
// program would with live frames: one Localizer, one Track call per frame, the estimate at once.
//
//   localize_drive ROUTE.sqlite DRIVE_DIR
//
// Prints one line per frame: frame, time, status, along-route s (m), lat, lon (deg), and the
// 6-DoF pose's status when the database is triangulated.
#include <cstdio>
#include <exception>

#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/localize/localizer.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s ROUTE.sqlite DRIVE_DIR\n", argv[0]);
    return 2;
  }
  try {
    const epiloc::Drive drive = epiloc::LoadDrive(argv[2]);
    const epiloc::FrameReader reader(drive);
    const epiloc::FramePositions gnss = epiloc::PositionFrames(drive, drive.gnss);
    epiloc::Localizer localizer(argv[1], drive.camera, epiloc::LocalizeOptions());
    std::printf("frame,timestamp_s,status,s_m,lat_deg,lon_deg,pose\n");
    for (size_t i = 0; i < drive.frames.size(); ++i) {
      epiloc::QueryFrame frame;
      frame.frame = drive.frames[i].frame;
      frame.timestamp_s = drive.frames[i].timestamp_s;
      frame.image = reader.ReadColour(i);
      if (gnss.per_frame[i]) frame.gnss = gnss.per_frame[i]->position;
      const epiloc::FrameEstimate estimate = localizer.Track(frame);
      const bool ok = estimate.status == epiloc::TrackStatus::kOk;
      std::printf("%lld,%.6f,%s,%.3f,%.9f,%.9f,%s\n", static_cast<long long>(estimate.frame),
                  estimate.timestamp_s, epiloc::TrackStatusName(estimate.status),
                  ok ? estimate.s_m : 0.0, ok ? estimate.position.lat_deg : 0.0,
                  ok ? estimate.position.lon_deg : 0.0,
                  estimate.refined ? epiloc::RefineStatusName(estimate.refined->status) : "");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "localize_drive: %s\n", e.what());
    return 1;
  }
  return 0;
}
