#include "mmval/particles/Dlvo.hpp"
