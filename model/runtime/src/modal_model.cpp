// Runtime reduced-modal model, float instantiation: what the appliance runs on a model image.
// The definitions are in modal_model_impl.hpp; modal_model_double.cpp instantiates the double
// model in its own translation unit.
#include "modal_model_impl.hpp"

namespace trainer::model {

template class BasicModalModel<float>;

}  // namespace trainer::model
