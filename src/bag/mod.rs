//! rosbag2 recordings in and out: MCAP and sqlite3 behind one reader and one writer.
