# Sources of imaging/io (appended to IMAGING_SOURCES).
list(APPEND IMAGING_SOURCES
  io/metaio_internal.cc
  io/volume_io.cc
  io/plus_sequence.cc
  io/sequence_reader.cc
  io/sequence_writer.cc
  io/async_sequence_writer.cc
  io/recording.cc
  io/em_log_import.cc)
list(APPEND IMAGING_PRIVATE_DEPS ${VTK_LIBRARIES} ZLIB::ZLIB)
list(APPEND IMAGING_SOURCES io/truth_fields.cc)
