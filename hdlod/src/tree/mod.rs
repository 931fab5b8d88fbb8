//! The HDLOD tree: the `hdlod-tree/1` format on disk and the cut.
