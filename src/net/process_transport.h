// SPDX-License-Identifier: MIT
#pragma once

// The transport of a process the user started: its ranks, and the links between them.

#include "net/emulated_link.h"
#include "net/transport.h"

#include <memory>
#include <string>

namespace occ {

struct ProcessTransport {
    std::unique_ptr<InProcessHub> hub;     // one rank without MPI: its hub (destroyed after the endpoint)
    std::unique_ptr<Transport> transport;  // this process's rank
    std::string links;                     // the emulated links, in words; empty when there are none
};

// True when this process runs under mpirun (Open MPI's OMPI_COMM_WORLD_SIZE or PMI's PMI_SIZE is
// set) in a build with the MPI transport.
bool underMpirun();

// This process's rank: an MPI rank under mpirun (underMpirun), else the one rank of an
// in-process hub; wrapped in emulated links when any is active. `every_pair` is the link
// between every pair of ranks; a non-empty `link_file` gives links per pair (readLinkTable, pairs
// it leaves out get `every_pair`). Throws InputError for a bad link file, and what MpiTransport
// throws when MPI cannot start.
ProcessTransport openProcessTransport(const LinkSpec& every_pair, const std::string& link_file);

}  // namespace occ
