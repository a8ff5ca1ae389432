# Warnings and sanitizers as INTERFACE targets, linked privately by every rayfarm target.
add_library(rayfarm_options INTERFACE)
add_library(rayfarm::options ALIAS rayfarm_options)
target_compile_options(rayfarm_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align -Woverloaded-virtual
  -Wno-unused-parameter)
# Bit-exact results across builds of the same binary: no fused multiply-add contraction, no fast math.
target_compile_options(rayfarm_options INTERFACE -ffp-contract=off -fno-fast-math)

if(RAYFARM_SANITIZE)
  target_compile_options(rayfarm_options INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  target_link_options(rayfarm_options INTERFACE -fsanitize=address,undefined)
endif()
