//! Readers and writers for the data formats users have (IMU/GNSS/nav text, RTKLIB .pos, generic
//! IMU CSV, KF-GINS YAML), with errors that name file, line and column.
