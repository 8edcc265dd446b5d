# Sources of imaging/sim (appended to IMAGING_SOURCES).
