// SPDX-License-Identifier: MIT
#include "net/process_transport.h"

#ifdef OCC_HAVE_MPI
#include "net/mpi_transport.h"
#endif

#include <algorithm>
#include <cstdlib>

namespace occ {

bool underMpirun() {
#ifdef OCC_HAVE_MPI
    return std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE");
#else
    return false;
#endif
}

ProcessTransport openProcessTransport(const LinkSpec& every_pair, const std::string& link_file) {
    ProcessTransport p;
#ifdef OCC_HAVE_MPI
    if (underMpirun()) p.transport = std::make_unique<MpiTransport>(nullptr, nullptr);
#endif
    if (!p.transport) {
        p.hub = std::make_unique<InProcessHub>(1);
        p.transport = p.hub->connect(0);
    }
    if (!link_file.empty()) {
        const int size = p.transport->size();
        const std::vector<std::vector<LinkSpec>> table = readLinkTable(link_file, size, every_pair);
        std::string pairs;
        for (int a = 0; a < size; ++a)
            for (int b = a + 1; b < size; ++b)
                pairs += (pairs.empty() ? "" : "; ") + std::to_string(a) + "-" + std::to_string(b) + " " +
                         table[size_t(a)][size_t(b)].describe();
        std::vector<LinkSpec> to = table[size_t(p.transport->rank())];
        if (std::any_of(to.begin(), to.end(), [](const LinkSpec& s) { return s.active(); }) || every_pair.active())
            p.transport = std::make_unique<EmulatedLink>(std::move(p.transport), std::move(to));
        p.links = "emulated per pair of ranks from " + link_file + ": " +
                  (pairs.empty() ? "(one rank: no pairs)" : pairs);
    } else if (every_pair.active()) {
        p.transport = std::make_unique<EmulatedLink>(std::move(p.transport), every_pair);
        p.links = "emulated between every pair of ranks: " + every_pair.describe();
    }
    return p;
}

}  // namespace occ
