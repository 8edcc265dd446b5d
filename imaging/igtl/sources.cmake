# Sources of imaging/igtl (appended to IMAGING_SOURCES).
