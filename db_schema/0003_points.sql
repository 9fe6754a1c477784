-- Schema version 3: local 3-D structure of the survey. Points triangulated from features matched
-- between survey frames with known poses, and their observations (which feature of which frame
-- sees the point). Positions in the database ENU frame, metres. Conventions: README.md.

CREATE TABLE points3d (
  point_id INTEGER PRIMARY KEY,
  e_m REAL NOT NULL,
  n_m REAL NOT NULL,
  u_m REAL NOT NULL,
  error_px REAL NOT NULL CHECK (error_px >= 0),
  num_observations INTEGER NOT NULL CHECK (num_observations >= 2)
);

-- `feature_index` = row of the frame's keypoints/descriptors blobs. A feature sees at most one
-- point; a point is seen at most once per frame.
CREATE TABLE observations (
  image_id INTEGER NOT NULL REFERENCES frames (image_id) ON DELETE CASCADE,
  feature_index INTEGER NOT NULL CHECK (feature_index >= 0),
  point_id INTEGER NOT NULL REFERENCES points3d (point_id) ON DELETE CASCADE,
  PRIMARY KEY (image_id, feature_index)
) WITHOUT ROWID;

CREATE INDEX observations_by_point ON observations (point_id);
