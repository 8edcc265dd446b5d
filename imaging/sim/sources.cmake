# Sources of imaging/sim (appended to IMAGING_SOURCES).
list(APPEND IMAGING_SOURCES sim/scene.cc sim/probe.cc sim/simulated_scanner.cc sim/catheter_scene.cc
  sim/water_tank_sweep.cc)
list(APPEND IMAGING_PRIVATE_DEPS embree TBB::tbb)
echoservo_sanitizer_hot_sources(sim/simulated_scanner.cc sim/probe.cc)
