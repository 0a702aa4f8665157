// Fixed-capacity vector that never allocates. FixedVector<T, N> owns inline storage and
// derives from the capacity-free FixedVectorRef<T>, so functions can take a
// FixedVectorRef<T>& without being templated on N (the ETL ivector pattern).
// push_back on a full vector returns false and leaves the vector unchanged.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <utility>

namespace trainer::core {

template <class T>
class FixedVectorRef {
 public:
  FixedVectorRef(const FixedVectorRef&) = delete;
  FixedVectorRef& operator=(const FixedVectorRef&) = delete;

  std::size_t size() const noexcept { return size_; }
  std::size_t capacity() const noexcept { return capacity_; }
  bool empty() const noexcept { return size_ == 0; }
  bool full() const noexcept { return size_ == capacity_; }

  [[nodiscard]] bool push_back(const T& value) noexcept {
    if (size_ == capacity_) return false;
    data_[size_++] = value;
    return true;
  }
  template <class... Args>
  [[nodiscard]] bool emplace_back(Args&&... args) noexcept {
    if (size_ == capacity_) return false;
    data_[size_++] = T{std::forward<Args>(args)...};
    return true;
  }
  void pop_back() noexcept {
    if (size_ > 0) --size_;
  }
  void clear() noexcept { size_ = 0; }
  // Shrinks, or grows with default-constructed elements; false if n exceeds capacity.
  [[nodiscard]] bool resize(std::size_t n) noexcept {
    if (n > capacity_) return false;
    for (std::size_t i = size_; i < n; ++i) data_[i] = T{};
    size_ = n;
    return true;
  }

  T& operator[](std::size_t i) noexcept { return data_[i]; }
  const T& operator[](std::size_t i) const noexcept { return data_[i]; }
  T& back() noexcept { return data_[size_ - 1]; }
  const T& back() const noexcept { return data_[size_ - 1]; }
  T* begin() noexcept { return data_; }
  T* end() noexcept { return data_ + size_; }
  const T* begin() const noexcept { return data_; }
  const T* end() const noexcept { return data_ + size_; }
  T* data() noexcept { return data_; }
  const T* data() const noexcept { return data_; }
  std::span<T> span() noexcept { return {data_, size_}; }
  std::span<const T> span() const noexcept { return {data_, size_}; }

 protected:
  FixedVectorRef(T* data, std::size_t capacity) noexcept : data_(data), capacity_(capacity) {}
  ~FixedVectorRef() = default;
  void rebind(T* data) noexcept { data_ = data; }
  void set_size(std::size_t n) noexcept { size_ = n; }

 private:
  T* data_;
  std::size_t size_ = 0;
  std::size_t capacity_;
};

namespace detail {
// Base-from-member: the storage must exist before FixedVectorRef is handed a pointer to it,
// so it lives in a base class listed first.
template <class T, std::size_t N>
struct FixedStorage {
  std::array<T, N> storage_{};
};
}  // namespace detail

template <class T, std::size_t N>
class FixedVector final : private detail::FixedStorage<T, N>, public FixedVectorRef<T> {
  static_assert(N > 0, "FixedVector needs a capacity");

 public:
  FixedVector() noexcept : FixedVectorRef<T>(this->storage_.data(), N) {}
  FixedVector(const FixedVector& other) noexcept : FixedVectorRef<T>(this->storage_.data(), N) {
    copy_from(other);
  }
  FixedVector& operator=(const FixedVector& other) noexcept {
    if (this != &other) copy_from(other);
    return *this;
  }
  ~FixedVector() = default;
  static constexpr std::size_t kCapacity = N;

 private:
  void copy_from(const FixedVector& other) noexcept {
    for (std::size_t i = 0; i < other.size(); ++i) this->storage_[i] = other[i];
    this->set_size(other.size());
  }
};

}  // namespace trainer::core
