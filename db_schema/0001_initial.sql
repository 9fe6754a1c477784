-- Schema version 1 of the epiloc route database: cameras, drives, frames with positions and
-- SIFT features, the route polyline. Units: metres, degrees, seconds; positions in the database
-- ENU frame (origin in meta). Conventions and blob layout: db_schema/README.md.

CREATE TABLE meta (
  key TEXT PRIMARY KEY NOT NULL,
  value TEXT NOT NULL
);

-- Two cameras per row: the distortion-free pinhole camera the features were extracted in
-- (width .. k3) and the original calibration of the drive's images (orig_width .. orig_k3).
-- Distortion in OpenCV's model and order k1, k2, p1, p2, k3.
CREATE TABLE cameras (
  camera_id INTEGER PRIMARY KEY,
  width INTEGER NOT NULL CHECK (width > 0),
  height INTEGER NOT NULL CHECK (height > 0),
  fx REAL NOT NULL CHECK (fx > 0),
  fy REAL NOT NULL CHECK (fy > 0),
  cx REAL NOT NULL,
  cy REAL NOT NULL,
  k1 REAL NOT NULL DEFAULT 0,
  k2 REAL NOT NULL DEFAULT 0,
  p1 REAL NOT NULL DEFAULT 0,
  p2 REAL NOT NULL DEFAULT 0,
  k3 REAL NOT NULL DEFAULT 0,
  orig_width INTEGER NOT NULL CHECK (orig_width > 0),
  orig_height INTEGER NOT NULL CHECK (orig_height > 0),
  orig_fx REAL NOT NULL CHECK (orig_fx > 0),
  orig_fy REAL NOT NULL CHECK (orig_fy > 0),
  orig_cx REAL NOT NULL,
  orig_cy REAL NOT NULL,
  orig_k1 REAL NOT NULL DEFAULT 0,
  orig_k2 REAL NOT NULL DEFAULT 0,
  orig_p1 REAL NOT NULL DEFAULT 0,
  orig_p2 REAL NOT NULL DEFAULT 0,
  orig_k3 REAL NOT NULL DEFAULT 0
);

CREATE TABLE drives (
  drive_id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE CHECK (name <> ''),
  source_dir TEXT NOT NULL DEFAULT '',
  camera_id INTEGER REFERENCES cameras (camera_id),
  positions TEXT NOT NULL DEFAULT '',
  num_frames_planned INTEGER NOT NULL DEFAULT 0 CHECK (num_frames_planned >= 0),
  complete INTEGER NOT NULL DEFAULT 0 CHECK (complete IN (0, 1))
);

-- One row per database image. (qw, qx, qy, qz) rotates camera-frame vectors into the database ENU
-- frame; all four are NULL when the positions carry no orientation.
CREATE TABLE frames (
  image_id INTEGER PRIMARY KEY,
  drive_id INTEGER NOT NULL REFERENCES drives (drive_id) ON DELETE CASCADE,
  frame INTEGER NOT NULL CHECK (frame >= 0),
  timestamp_s REAL NOT NULL,
  image_path TEXT NOT NULL DEFAULT '',
  image_hash TEXT NOT NULL DEFAULT '',
  lat_deg REAL NOT NULL CHECK (lat_deg BETWEEN -90 AND 90),
  lon_deg REAL NOT NULL CHECK (lon_deg BETWEEN -180 AND 180),
  alt_m REAL NOT NULL,
  e_m REAL NOT NULL,
  n_m REAL NOT NULL,
  u_m REAL NOT NULL,
  heading_deg REAL NOT NULL CHECK (heading_deg >= 0 AND heading_deg < 360),
  s_m REAL NOT NULL,
  qw REAL,
  qx REAL,
  qy REAL,
  qz REAL,
  num_features INTEGER NOT NULL DEFAULT 0 CHECK (num_features >= 0),
  UNIQUE (drive_id, frame),
  CHECK ((qw IS NULL) = (qx IS NULL) AND (qw IS NULL) = (qy IS NULL) AND
         (qw IS NULL) = (qz IS NULL))
);

CREATE INDEX frames_by_drive_time ON frames (drive_id, timestamp_s);

-- Feature blobs: `rows` features of `cols` values, row-major, little-endian (README.md).
CREATE TABLE keypoints (
  image_id INTEGER PRIMARY KEY REFERENCES frames (image_id) ON DELETE CASCADE,
  rows INTEGER NOT NULL CHECK (rows >= 0),
  cols INTEGER NOT NULL CHECK (cols = 4),
  data BLOB NOT NULL CHECK (length(data) = rows * cols * 4)
);

CREATE TABLE descriptors (
  image_id INTEGER PRIMARY KEY REFERENCES frames (image_id) ON DELETE CASCADE,
  rows INTEGER NOT NULL CHECK (rows >= 0),
  cols INTEGER NOT NULL CHECK (cols = 128),
  data BLOB NOT NULL CHECK (length(data) = rows * cols)
);

-- The route polyline in travel order (idx 0, 1, ...), database ENU frame.
CREATE TABLE route_points (
  idx INTEGER PRIMARY KEY CHECK (idx >= 0),
  e_m REAL NOT NULL,
  n_m REAL NOT NULL,
  u_m REAL NOT NULL
);
