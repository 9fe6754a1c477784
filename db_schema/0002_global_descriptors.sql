-- Schema version 2: whole-image retrieval. The retrieval model (visual words and PCA whitening of
-- VLAD vectors, one row) and one global descriptor per frame. Blob layouts: README.md.

CREATE TABLE retrieval_model (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  num_words INTEGER NOT NULL CHECK (num_words > 0),
  dims INTEGER NOT NULL CHECK (dims > 0),
  data BLOB NOT NULL
);

-- `dims` float32 values, little-endian.
CREATE TABLE global_descriptors (
  image_id INTEGER PRIMARY KEY REFERENCES frames (image_id) ON DELETE CASCADE,
  dims INTEGER NOT NULL CHECK (dims > 0),
  data BLOB NOT NULL CHECK (length(data) = dims * 4)
);
