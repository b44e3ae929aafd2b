//! Serde mirrors of the ROS 2 messages fdavar reads and writes (CDR field order), no ROS client types.
