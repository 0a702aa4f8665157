# Published shell results through the real `modelc static` binary (fixtures written by
# tools/gen_plate_msh.py), and the modal builder → image → loader → runtime chain.
# Included from tests/model/offline/CMakeLists.txt (include(published.cmake)); paths are
# relative to this file.
trainer_test(NAME modelc_published_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/modelc_published_test.cpp
             LIBS trainer::model_offline nlohmann_json::nlohmann_json LABELS unit
             NOT_UNDER_SANITIZERS)
if(TARGET modelc_published_test)
  target_compile_definitions(modelc_published_test PRIVATE MODELC_PATH="$<TARGET_FILE:modelc>")
  add_dependencies(modelc_published_test modelc)
endif()

trainer_test(NAME model_offline_modal_build_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/modal_build_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit)

# The duct's speed/accuracy trade study and `--error-budget`'s choice (small tube).
trainer_test(NAME model_offline_modal_tradeoff_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/modal_tradeoff_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit)
