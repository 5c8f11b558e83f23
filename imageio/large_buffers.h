#pragma once
// Image-sized buffers on transparent huge pages. A 4000 x 3000 frame and its masks and labels are tens of MB of
// fresh memory in every process that reads one, and on the 2-core development VM every fresh 4 KB page costs
// ~20-30 us in the page-fault handler: a `detect` of a blank frame spent ~40 % of its CPU there. A huge page is
// one fault for 2 MB. With THP in `madvise` mode (Debian's default) the kernel gives huge pages only to memory
// advised so (madvise(2), MADV_HUGEPAGE); this gives every cv::Mat buffer of at least 2 MB a mapping of its own,
// aligned to and rounded up to whole huge pages and advised, so that all of it can be huge (a buffer's rounding costs
// at most 2 MB). Pixels and results do not change, only how memory is mapped.
// A library never changes the allocator of the program that links it: programs call this (tools/main.cc), before
// their first image.
namespace topocal::imageio {

void UseHugePagesForImageBuffers();

}  // namespace topocal::imageio
