# Sources of imaging/io (appended to IMAGING_SOURCES).
