# Cotin's tensor model (precompute → image → runtime, against the direct sparse solve), and
# displacement-driven tool contact on the modal duct.
# Included from tests/model/offline/CMakeLists.txt.
trainer_test(NAME model_tensor_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/tensor_model_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit)

# Displacement-driven tool contact on the modal duct (built offline, loaded, stepped).
trainer_test(NAME model_contact_test
             SOURCES ${CMAKE_CURRENT_LIST_DIR}/displacement_contact_test.cpp
             LIBS trainer::model_offline trainer::model LABELS unit)
