# Modal analysis, residual compliance, DNIOS and the offline → runtime modal chain.
# Included from tests/model/offline/CMakeLists.txt (include(modal.cmake)); paths are relative
# to this file so the lines also work from another including project.
trainer_test(NAME model_offline_modal_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/modal_analysis_test.cpp
                     ${CMAKE_CURRENT_LIST_DIR}/modal_residual_test.cpp
                     ${CMAKE_CURRENT_LIST_DIR}/modal_dnios_test.cpp
                     ${CMAKE_CURRENT_LIST_DIR}/modal_runtime_test.cpp
                     ${CMAKE_CURRENT_LIST_DIR}/modal_shell_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit NOT_UNDER_SANITIZERS)
