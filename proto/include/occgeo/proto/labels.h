#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "occgeo/v1/control.pb.h"
#include "occgeo/v1/query.pb.h"

// The names people type and read for the protocol's enums: the value's name without its type's prefix, in lower case
// (BEHAVIOUR_GOTO is "goto", BEHAVIOUR_STATE_STEER_GAP is "steer_gap", MODEL_GRID is "grid"). Taken from the schema
// itself, so a value added to a .proto file has its label with nothing else to edit. The UNSPECIFIED values' label is
// "", a value this build does not know is its number.

namespace occgeo::proto {

[[nodiscard]] std::string behaviour_label(v1::Behaviour behaviour);
[[nodiscard]] std::string behaviour_state_label(v1::BehaviourState state);
[[nodiscard]] std::string model_label(v1::Model model);

// The value a label names; nullopt for an unknown label and for "unspecified".
[[nodiscard]] std::optional<v1::Behaviour> behaviour_from_label(std::string_view label);
[[nodiscard]] std::optional<v1::BehaviourState> behaviour_state_from_label(std::string_view label);

// Every label of Behaviour but "unspecified", in the schema's order, joined as "bearcat, bearcat_seed, ..." for
// error messages and help texts.
[[nodiscard]] std::string behaviour_labels();

}  // namespace occgeo::proto
