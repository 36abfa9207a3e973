// DLVO interaction of a sphere with a plate or another sphere (placeholder; see Dlvo.cpp).
#pragma once
