// fvr-render: headless Fourier volume rendering from the command line. The command line is
// declared in render_cli/options.cpp, the run in render_cli/run.cpp.
#include <iostream>
#include <new>

#include <fvr/core/errors.h>

#include "render_cli/options.h"
#include "render_cli/run.h"

int main(int argc, char** argv) {
    using namespace fvr::core;
    try {
        const auto options = fvr::cli::parseOptions(argc, argv);
        if (!options) return 0; // --help
        return fvr::cli::run(*options);
    } catch (const InputError& e) {
        std::cerr << "fvr-render: error: " << e.what() << "\n";
        return 2;
    } catch (const std::bad_alloc&) {
        std::cerr << "fvr-render: error: out of memory (try a smaller --oversampling or --size)\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "fvr-render: error: " << e.what() << "\n";
        return 1;
    }
}
