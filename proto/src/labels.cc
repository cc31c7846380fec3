#include "occgeo/proto/labels.h"

#include <cctype>

#include <google/protobuf/descriptor.h>

namespace occgeo::proto {
namespace {

// The enum's values are all named "<PREFIX>_<NAME>", the prefix being the type's name in upper snake case.
std::string label_of(const google::protobuf::EnumDescriptor& type, int number, std::string_view prefix) {
  if (number == 0) return {};  // every enum's UNSPECIFIED: nothing set
  const google::protobuf::EnumValueDescriptor* value = type.FindValueByNumber(number);
  if (value == nullptr) return std::to_string(number);
  std::string_view name = value->name();
  if (name.starts_with(prefix)) name.remove_prefix(prefix.size());
  std::string label(name);
  for (char& c : label) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return label;
}

std::optional<int> number_of(const google::protobuf::EnumDescriptor& type, std::string_view label,
                             std::string_view prefix) {
  std::string name(prefix);
  for (const char c : label) {
    // Only a lower-case label is one: "GOTO" is not typed by people and would also match BEHAVIOUR_GOTO.
    if (std::isupper(static_cast<unsigned char>(c))) return std::nullopt;
    name.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
  }
  const google::protobuf::EnumValueDescriptor* value = type.FindValueByName(name);
  if (value == nullptr || value->number() == 0) return std::nullopt;
  return value->number();
}

constexpr std::string_view kBehaviourPrefix = "BEHAVIOUR_";
constexpr std::string_view kBehaviourStatePrefix = "BEHAVIOUR_STATE_";

}  // namespace

std::string behaviour_label(v1::Behaviour behaviour) {
  return label_of(*v1::Behaviour_descriptor(), behaviour, kBehaviourPrefix);
}

std::string behaviour_state_label(v1::BehaviourState state) {
  return label_of(*v1::BehaviourState_descriptor(), state, kBehaviourStatePrefix);
}

std::string model_label(v1::Model model) { return label_of(*v1::Model_descriptor(), model, "MODEL_"); }

std::optional<v1::Behaviour> behaviour_from_label(std::string_view label) {
  const auto number = number_of(*v1::Behaviour_descriptor(), label, kBehaviourPrefix);
  if (!number) return std::nullopt;
  return static_cast<v1::Behaviour>(*number);
}

std::optional<v1::BehaviourState> behaviour_state_from_label(std::string_view label) {
  const auto number = number_of(*v1::BehaviourState_descriptor(), label, kBehaviourStatePrefix);
  if (!number) return std::nullopt;
  return static_cast<v1::BehaviourState>(*number);
}

std::string behaviour_labels() {
  const google::protobuf::EnumDescriptor& type = *v1::Behaviour_descriptor();
  std::string joined;
  for (int i = 0; i < type.value_count(); ++i) {
    if (type.value(i)->number() == 0) continue;
    if (!joined.empty()) joined += ", ";
    joined += label_of(type, type.value(i)->number(), kBehaviourPrefix);
  }
  return joined;
}

}  // namespace occgeo::proto
