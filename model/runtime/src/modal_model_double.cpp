// Runtime reduced-modal model, double instantiation (ModalModelDouble): the same algorithms on
// double data, for measuring what float32 storage costs. Kept apart from the float
// instantiation (modal_model.cpp) so that each compiles as if it were the only one.
#include "modal_model_impl.hpp"

namespace trainer::model {

template class BasicModalModel<double>;

}  // namespace trainer::model
