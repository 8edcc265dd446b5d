# Sources of imaging/render (appended to IMAGING_SOURCES).
