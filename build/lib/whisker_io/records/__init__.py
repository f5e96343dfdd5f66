"""The session data types (:mod:`~whisker_io.records.whisk_record`) and their files
(:mod:`~whisker_io.records.recording`: per-whisk CSVs and the pose log)."""
