# Trade studies of the catheter (particle count) and of the tensor model (contact cap): errors
# against their references and cycle costs. Included from tests/model/offline/CMakeLists.txt.
trainer_test(NAME model_tradeoff_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/catheter_tradeoff_test.cpp
                     ${CMAKE_CURRENT_LIST_DIR}/tensor_tradeoff_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit)
