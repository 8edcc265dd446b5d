# Sources of imaging/render (appended to IMAGING_SOURCES).
# The 2D slice/MIP panel is drawn with OpenCV and written with VTK's PNG writer (png_file:
# OpenCV's imgcodecs would load ~100 more shared libraries into every process); the 3D view
# uses VTK rendering, which needs an X server here (no OSMesa/EGL), hence X11 to check the
# display before any VTK window exists.
# find_package(VTK) replaces VTK_LIBRARIES: keep what the other parts found and add ours,
# so that vtk_module_autoinit (end of imaging/CMakeLists.txt) sees them all.
set(_render_vtk_before ${VTK_LIBRARIES})
find_package(VTK 9.1 REQUIRED COMPONENTS RenderingCore RenderingOpenGL2 RenderingFreeType
  InteractionStyle RenderingVolumeOpenGL2 FiltersCore FiltersSources IOImage)
set(ECHOSERVO_RENDER_VTK_LIBRARIES ${VTK_LIBRARIES})
list(APPEND VTK_LIBRARIES ${_render_vtk_before})
list(REMOVE_DUPLICATES VTK_LIBRARIES)
find_package(X11 REQUIRED)

list(APPEND IMAGING_SOURCES
  render/png_file.cc
  render/volume_render.cc
  render/volume_render_3d.cc
  render/x_display.cc)
list(APPEND IMAGING_PRIVATE_DEPS
  opencv_core opencv_imgproc
  ${ECHOSERVO_RENDER_VTK_LIBRARIES} X11::X11)
