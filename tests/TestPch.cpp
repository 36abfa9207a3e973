// The translation unit that builds the tests' shared precompiled header
// (tests/CMakeLists.txt, mmval_test_pch); it holds no tests.
