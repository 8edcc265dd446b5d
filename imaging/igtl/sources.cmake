# Sources of imaging/igtl (appended to IMAGING_SOURCES): the OpenIGTLink IMAGE codec, the
# scanner server, the ingest client and a synthetic phantom source. libOpenIGTLink has no
# imported target; its include directory is added (SYSTEM, PRIVATE) after the target in
# imaging/CMakeLists.txt. UseOpenIGTLink.cmake is deliberately not included (it adds
# -fno-tree-vectorize).
list(APPEND IMAGING_SOURCES
  igtl/crc64.cc
  igtl/image_message.cc
  igtl/tracking_encode.cc
  igtl/tracking_decode.cc
  igtl/tcp.cc
  igtl/image_server.cc
  igtl/detection_server.cc
  igtl/client_connection.cc
  igtl/ingest.cc
  igtl/em_stream.cc
  igtl/phantom_source.cc)
find_package(Threads REQUIRED)
list(APPEND IMAGING_PRIVATE_DEPS ${OpenIGTLink_LIBRARIES} Threads::Threads)
