# Cotin's tensor model: precompute → image → runtime, against the direct sparse solve.
# Included from tests/model/offline/CMakeLists.txt.
trainer_test(NAME model_tensor_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/tensor_model_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit)
