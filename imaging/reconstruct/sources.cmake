# Sources of imaging/reconstruct (appended to IMAGING_SOURCES): freehand 3D reconstruction
# of tracked 2D sweeps (docs/reconstruction.md).
list(APPEND IMAGING_SOURCES reconstruct/freehand_reconstruction.cc)
echoservo_sanitizer_hot_sources(reconstruct/freehand_reconstruction.cc)
